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


def _p_series(a: float, x: float, lg: float) -> float:
    term = total = 1.0 / a
    ap = a
    for _ in range(10_000):
        ap += 1.0
        term *= x / ap
        total += term
        if abs(term) < abs(total) * _EPS:
            break
    return total * np.exp(-x + a * np.log(x) - lg)


def _q_fraction(a: float, x: float, lg: float) -> float:
    """Upper regularised gamma Q(a, x) by the continued fraction (modified Lentz), x >= a + 1."""
    tiny = 1e-300
    b = x + 1.0 - a
    c = 1.0 / tiny
    d = 1.0 / b
    h = d
    for i in range(1, 10_000):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = tiny if abs(d) < tiny else d
        c = b + an / c
        c = tiny if abs(c) < tiny else c
        d = 1.0 / d
        step = d * c
        h *= step
        if abs(step - 1.0) < _EPS:
            break
    return np.exp(-x + a * np.log(x) - lg) * h


def _p_quadrature(a: float, x: float, lg: float) -> float:
    """P(a, x) for large a: the integral of the density from x to where it is negligible."""
    a1 = a - 1.0
    s = np.sqrt(a1)
    if x > a1:
        top = max(a1 + 11.5 * s, x + 6.0 * s)
    else:
        top = max(0.0, min(a1 - 7.5 * s, x - 5.0 * s))
    t = x + (top - x) * _GL_T
    log_f = -(t - a1) + a1 * (np.log(t) - np.log(a1))
    part = float(np.sum(_GL_W * np.exp(log_f))) * (top - x) * np.exp(a1 * (np.log(a1) - 1.0) - lg)
    return 1.0 - part if x > a1 else -part  # the integral upward is Q; downward (negative) it is -P


def gamma_p(a: float, x: float) -> float:
    """Regularised lower incomplete gamma P(a, x) = gamma(a, x) / Gamma(a), a > 0, x >= 0."""
    if x <= 0.0:
        return 0.0
    lg = lgamma(a)
    if a > _LARGE_A:
        return _p_quadrature(a, x, lg)
    if x < a + 1.0:
        return min(1.0, _p_series(a, x, lg))
    return max(0.0, 1.0 - _q_fraction(a, x, lg))


def _ppf_gamma(q: float, a: float) -> float:
    """x with P(a, x) = q (0 < q < 1), by Halley's iteration."""
    lg = lgamma(a)
    if a > 1.0:  # Wilson-Hilferty: chi2 quantile of 2a dof, halved
        z = _normal_ppf(q)
        h = 1.0 / (9.0 * a)
        x = max(1e-3 * a, a * (1.0 - h + z * np.sqrt(h)) ** 3)
    else:
        x = np.exp((np.log(q) + np.log(a) + lg) / a)  # P ~ x^a / (a Gamma(a)) for small x
        x = min(x, 1.0) if q < 0.9 else max(x, 1.0 - np.log1p(-q))
    a1 = a - 1.0
    for _ in range(100):
        err = gamma_p(a, x) - q
        dens = np.exp(a1 * np.log(x) - x - lg)  # dP/dx
        if dens <= 0.0:
            break
        u = err / dens
        step = u / (1.0 - 0.5 * min(1.0, u * (a1 / x - 1.0)))  # Halley
        x_new = x - step
        if x_new <= 0.0:
            x_new = 0.5 * x
        if abs(x_new - x) <= 1e-13 * x_new:
            return float(x_new)
        x = x_new
    return float(x)


def _normal_ppf(q: float) -> float:
    """Standard normal quantile (Acklam's rational approximation, relative 1e-9), a starting value."""
    a = (-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02, 1.383577518672690e+02,
         -3.066479806614716e+01, 2.506628277459239e+00)
    b = (-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02, 6.680131188771972e+01,
         -1.328068155288572e+01)
    c = (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00, -2.549732539343734e+00,
         4.374664141464968e+00, 2.938163982698783e+00)
    d = (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00, 3.754408661907416e+00)
    if q < 0.02425 or q > 0.97575:
        r = np.sqrt(-2.0 * np.log(q if q < 0.5 else 1.0 - q))
        v = (((((c[0] * r + c[1]) * r + c[2]) * r + c[3]) * r + c[4]) * r + c[5]) / \
            ((((d[0] * r + d[1]) * r + d[2]) * r + d[3]) * r + 1.0)
        return v if q < 0.5 else -v
    r = q - 0.5
    s = r * r
    return (((((a[0] * s + a[1]) * s + a[2]) * s + a[3]) * s + a[4]) * s + a[5]) * r / \
        (((((b[0] * s + b[1]) * s + b[2]) * s + b[3]) * s + b[4]) * s + 1.0)


def chi2_ppf(q: float | np.ndarray, dof: float | np.ndarray) -> np.ndarray:
    """Quantile of the chi-squared law with ``dof`` degrees of freedom (as scipy.stats.chi2.ppf).

    ``q`` and ``dof`` broadcast; NaN where dof is not finite and positive or q not in (0, 1).
    """
    qq, dd = np.broadcast_arrays(np.asarray(q, float), np.asarray(dof, float))
    out = np.full(qq.shape, np.nan)
    for idx in np.ndindex(qq.shape):
        qi, di = float(qq[idx]), float(dd[idx])
        if 0.0 < qi < 1.0 and np.isfinite(di) and di > 0:
            out[idx] = 2.0 * _ppf_gamma(qi, 0.5 * di)
    return out if out.ndim else out[()]
