"""Chi-squared quantiles for the confidence intervals of the stability statistics, numpy only.

The intervals of every Allan-type point need chi2.ppf at the equivalent degrees of freedom
(0.1 to ~1e7, not integers). scipy.special / scipy.stats would do it, but importing them costs
0.3-1 s of CPU, more than the whole ``workbench allan`` analysis of a 1e6-sample record; this
module computes the quantile from the regularised lower incomplete gamma function P(a, x):

* P by its power series for x < a + 1 and by the Legendre continued fraction (modified Lentz)
  otherwise (Abramowitz & Stegun 6.5.29, 6.5.31); for a > 100 by 24-point Gauss-Legendre
  quadrature of the integrand t^(a-1) e^-t over the few standard deviations around x where it
  is not negligible (the series would need O(sqrt a) terms).
* The quantile by Halley's iteration on P(a, x) = q from the Wilson-Hilferty guess (for small
  a the guess x = (q a Gamma(a))^(1/a) of the series' first term), kept positive.

Every step runs on whole arrays (the thousands of quantiles of ``--taus all`` in one pass); an
element leaves an iteration when it has converged, so each value is the one a scalar iteration
would give.

Accuracy: quantiles relative 1e-10 against scipy.stats.chi2.ppf over dof 0.05-1e7, q 1e-4-0.9999
(P itself relative 2e-9)
(tests/analysis/test_chi2.py).

Public: :func:`gamma_p`, :func:`chi2_ppf`.
"""

from __future__ import annotations

from math import lgamma

import numpy as np

_GL_T, _GL_W = np.polynomial.legendre.leggauss(24)
_GL_T, _GL_W = 0.5 * (_GL_T + 1.0), 0.5 * _GL_W  # nodes and weights on [0, 1]
_EPS = 1e-15
_LARGE_A = 100.0
_MAX_TERMS = 10_000  # series terms / continued-fraction levels (a <= 100 converges in far fewer)


def _lgamma(a: np.ndarray) -> np.ndarray:
    return np.array([lgamma(v) for v in a.ravel()]).reshape(a.shape)


def _p_series(a: np.ndarray, x: np.ndarray, lg: np.ndarray) -> np.ndarray:
    term = 1.0 / a
    total = term.copy()
    ap = a.copy()
    live = np.arange(len(a))
    for _ in range(_MAX_TERMS):
        ap[live] += 1.0
        term[live] *= x[live] / ap[live]
        total[live] += term[live]
        live = live[~(np.abs(term[live]) < np.abs(total[live]) * _EPS)]
        if not len(live):
            break
    return total * np.exp(-x + a * np.log(x) - lg)


def _q_fraction(a: np.ndarray, x: np.ndarray, lg: np.ndarray) -> np.ndarray:
    """Upper regularised gamma Q(a, x) by the continued fraction (modified Lentz), x >= a + 1."""
    tiny = 1e-300
    b = x + 1.0 - a
    c = np.full(len(a), 1.0 / tiny)
    d = 1.0 / b
    h = d.copy()
    live = np.arange(len(a))
    for i in range(1, _MAX_TERMS):
        an = -i * (i - a[live])
        b[live] += 2.0
        dl = an * d[live] + b[live]
        dl = np.where(np.abs(dl) < tiny, tiny, dl)
        cl = b[live] + an / c[live]
        cl = np.where(np.abs(cl) < tiny, tiny, cl)
        d[live] = dl = 1.0 / dl
        c[live] = cl
        step = dl * cl
        h[live] *= step
        live = live[~(np.abs(step - 1.0) < _EPS)]
        if not len(live):
            break
    return np.exp(-x + a * np.log(x) - lg) * h


def _p_quadrature(a: np.ndarray, x: np.ndarray, lg: np.ndarray) -> np.ndarray:
    """P(a, x) for large a: the integral of the density from x to where it is negligible."""
    a1 = a - 1.0
    s = np.sqrt(a1)
    up = x > a1
    top = np.where(up, np.maximum(a1 + 11.5 * s, x + 6.0 * s),
                   np.maximum(0.0, np.minimum(a1 - 7.5 * s, x - 5.0 * s)))
    t = x[:, None] + (top - x)[:, None] * _GL_T
    log_f = -(t - a1[:, None]) + a1[:, None] * (np.log(t) - np.log(a1)[:, None])
    part = (np.exp(log_f) @ _GL_W) * (top - x) * np.exp(a1 * (np.log(a1) - 1.0) - lg)
    return np.where(up, 1.0 - part, -part)  # the integral upward is Q; downward (negative) it is -P


def _gamma_p(a: np.ndarray, x: np.ndarray, lg: np.ndarray) -> np.ndarray:
    """P(a, x) of 1-D arrays, ``lg`` = lgamma(a)."""
    out = np.zeros(len(a))
    large = (x > 0.0) & (a > _LARGE_A)
    series = (x > 0.0) & ~large & (x < a + 1.0)
    fraction = (x > 0.0) & ~large & ~series
    if large.any():
        out[large] = _p_quadrature(a[large], x[large], lg[large])
    if series.any():
        p = _p_series(a[series], x[series], lg[series])
        out[series] = np.where(p < 1.0, p, 1.0)
    if fraction.any():
        p = 1.0 - _q_fraction(a[fraction], x[fraction], lg[fraction])
        out[fraction] = np.where(p > 0.0, p, 0.0)
    return out


def gamma_p(a: float | np.ndarray, x: float | np.ndarray) -> np.ndarray:
    """Regularised lower incomplete gamma P(a, x) = gamma(a, x) / Gamma(a), a > 0, x >= 0
    (``a`` and ``x`` broadcast)."""
    aa, xx = np.broadcast_arrays(np.asarray(a, float), np.asarray(x, float))
    out = _gamma_p(aa.ravel(), xx.ravel(), _lgamma(aa.ravel())).reshape(aa.shape)
    return out if out.ndim else out[()]


def _ppf_gamma(q: np.ndarray, a: np.ndarray) -> np.ndarray:
    """x with P(a, x) = q (0 < q < 1, 1-D arrays), by Halley's iteration."""
    lg = _lgamma(a)
    z = _normal_ppf(q)
    h = 1.0 / (9.0 * a)
    with np.errstate(invalid="ignore"):  # the Wilson-Hilferty branch is computed for a <= 1 too
        wilson = np.maximum(1e-3 * a, a * (1.0 - h + z * np.sqrt(h)) ** 3)  # chi2 quantile of 2a dof, halved
    small = np.exp((np.log(q) + np.log(a) + lg) / a)  # P ~ x^a / (a Gamma(a)) for small x
    small = np.where(q < 0.9, np.minimum(small, 1.0), np.maximum(small, 1.0 - np.log1p(-q)))
    x = np.where(a > 1.0, wilson, small)
    a1 = a - 1.0
    live = np.arange(len(a))
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        for _ in range(100):
            al, xl, lgl = a[live], x[live], lg[live]
            err = _gamma_p(al, xl, lgl) - q[live]
            dens = np.exp(a1[live] * np.log(xl) - xl - lgl)  # dP/dx
            go = ~(dens <= 0.0)
            live, xl, err, dens = live[go], xl[go], err[go], dens[go]
            u = err / dens
            v = u * (a1[live] / xl - 1.0)
            step = u / (1.0 - 0.5 * np.where(v < 1.0, v, 1.0))  # Halley
            x_new = xl - step
            x_new = np.where(x_new <= 0.0, 0.5 * xl, x_new)
            x[live] = x_new
            live = live[~(np.abs(x_new - xl) <= 1e-13 * x_new)]
            if not len(live):
                break
    return x


def _normal_ppf(q: np.ndarray) -> np.ndarray:
    """Standard normal quantile (Acklam's rational approximation, relative 1e-9), a starting value."""
    a = (-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02, 1.383577518672690e+02,
         -3.066479806614716e+01, 2.506628277459239e+00)
    b = (-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02, 6.680131188771972e+01,
         -1.328068155288572e+01)
    c = (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00, -2.549732539343734e+00,
         4.374664141464968e+00, 2.938163982698783e+00)
    d = (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00, 3.754408661907416e+00)
    r = np.sqrt(-2.0 * np.log(np.where(q < 0.5, q, 1.0 - q)))
    v = (((((c[0] * r + c[1]) * r + c[2]) * r + c[3]) * r + c[4]) * r + c[5]) / \
        ((((d[0] * r + d[1]) * r + d[2]) * r + d[3]) * r + 1.0)
    tail = np.where(q < 0.5, v, -v)
    r = q - 0.5
    s = r * r
    central = (((((a[0] * s + a[1]) * s + a[2]) * s + a[3]) * s + a[4]) * s + a[5]) * r / \
        (((((b[0] * s + b[1]) * s + b[2]) * s + b[3]) * s + b[4]) * s + 1.0)
    return np.where((q < 0.02425) | (q > 0.97575), tail, central)


def chi2_ppf(q: float | np.ndarray, dof: float | np.ndarray) -> np.ndarray:
    """Quantile of the chi-squared law with ``dof`` degrees of freedom (as scipy.stats.chi2.ppf).

    ``q`` and ``dof`` broadcast; NaN where dof is not finite and positive or q not in (0, 1).
    """
    qq, dd = np.broadcast_arrays(np.asarray(q, float), np.asarray(dof, float))
    qf, df = qq.ravel(), dd.ravel()
    ok = (0.0 < qf) & (qf < 1.0) & np.isfinite(df) & (df > 0)
    out = np.full(qf.shape, np.nan)
    if ok.any():
        out[ok] = 2.0 * _ppf_gamma(qf[ok], 0.5 * df[ok])
    out = out.reshape(qq.shape)
    return out if out.ndim else out[()]
