"""Non-negative least squares and bracketed root finding for the small noise-model fits, numpy only.

The IEEE 952 and GMWM fits solve problems of at most a few dozen unknowns thousands of times;
scipy.optimize would do it, but importing it costs ~0.5 s of CPU, more than the whole
``workbench allan`` analysis of a 1e6-sample record. Both algorithms are textbook:

* :func:`nnls`: Lawson & Hanson, *Solving Least Squares Problems* (1974), ch. 23 (active set;
  each passive-set solve by numpy.linalg.lstsq).
* :func:`root_bracket`: the Illinois variant of regula falsi (Dowell & Jarratt 1971), which keeps
  the bracket and converges superlinearly.
* :func:`minimize_bounded`: Brent's minimiser on an interval (golden section with parabolic
  steps; Brent, *Algorithms for Minimization without Derivatives* (1973), ch. 5, the algorithm
  of scipy.optimize.fminbound).

They are tested against scipy.optimize.nnls / brentq / minimize_scalar (tests/analysis/test_small_solvers.py).

Public: :func:`nnls`, :func:`root_bracket`, :func:`minimize_bounded`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def nnls(a: np.ndarray, b: np.ndarray, max_iter: int | None = None) -> tuple[np.ndarray, float]:
    """argmin ||a x - b||_2 subject to x >= 0; returns (x (n,), residual norm) as scipy's nnls.

    ``a`` (m, n), ``b`` (m,), any consistent units.
    """
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):  # an overflowed weighting: no solution
        return np.full(a.shape[1], np.nan), float("nan")
    # columns scaled to unit peak (x >= 0 is invariant under positive column scales): the noise
    # bases span 20 decades, which would otherwise swamp the gradient test
    scale = np.abs(a).max(axis=0, initial=0.0)
    scale[scale == 0] = 1.0
    an = a / scale
    n = a.shape[1]
    x = np.zeros(n)
    passive = np.zeros(n, bool)
    b_scale = float(np.abs(b).max(initial=0.0))
    if b_scale == 0.0:
        return x, 0.0
    b = b / b_scale  # the problem is homogeneous in b: solved at unit scale, no overflow
    tol = 10.0 * np.finfo(float).eps * max(a.shape) ** 2
    w = an.T @ b
    limit = max_iter if max_iter is not None else 3 * n
    for _ in range(limit):
        if passive.all() or not np.any(w[~passive] > tol):
            break
        passive[int(np.argmax(np.where(passive, -np.inf, w)))] = True
        while True:
            z = np.zeros(n)
            z[passive] = np.linalg.lstsq(an[:, passive], b, rcond=None)[0]
            if np.all(z[passive] > 0):
                break
            neg = np.flatnonzero(passive & (z <= 0))
            ratios = x[neg] / (x[neg] - z[neg])
            x = x + float(ratios.min()) * (z - x)
            passive &= x > 0
            passive[neg[int(np.argmin(ratios))]] = False  # the blocking variable leaves (no rounding loop)
            x[~passive] = 0.0
        x = z
        w = an.T @ (b - an @ x)
    return x / scale * b_scale, float(np.linalg.norm(an @ x - b)) * b_scale


def root_bracket(f: Callable[[float], float], lo: float, hi: float, xtol: float = 1e-12, rtol: float = 1e-10,
                 max_iter: int = 200) -> float:
    """A root of ``f`` in [lo, hi], where f(lo) and f(hi) differ in sign (Illinois regula falsi).

    Stops when the bracket is narrower than ``xtol + rtol |x|``; raises ValueError when the ends
    have the same sign.
    """
    f_lo, f_hi = f(lo), f(hi)
    if f_lo == 0.0:
        return lo
    if f_hi == 0.0:
        return hi
    if np.sign(f_lo) == np.sign(f_hi):
        raise ValueError("root_bracket: f(lo) and f(hi) have the same sign")
    side = 0
    x = lo
    for _ in range(max_iter):
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):  # an infinite end: bisect
            x = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        if not lo < x < hi:
            x = 0.5 * (lo + hi)
        fx = f(x)
        if fx == 0.0:
            return x
        if np.sign(fx) == np.sign(f_hi):
            hi, f_hi = x, fx
            if side == 1:
                f_lo *= 0.5
            side = 1
        else:
            lo, f_lo = x, fx
            if side == -1:
                f_hi *= 0.5
            side = -1
        if hi - lo <= xtol + rtol * abs(x):
            break
    return float(0.5 * (lo + hi)) if hi - lo <= xtol + rtol * abs(x) else float(x)


def minimize_bounded(f: Callable[[float], float], lo: float, hi: float, xtol: float = 1e-5,
                     max_iter: int = 500) -> tuple[float, float]:
    """A local minimum (x, f(x)) of ``f`` on [lo, hi] by Brent's method (never evaluates the ends).

    Stops when x is known to within ``xtol + sqrt(eps) |x|``; an infinite f(x) falls back to
    golden-section steps.
    """
    golden = 0.5 * (3.0 - np.sqrt(5.0))
    sqrt_eps = float(np.sqrt(np.finfo(float).eps))
    a, b = float(lo), float(hi)
    x = w = v = a + golden * (b - a)
    fx = fw = fv = f(x)
    d = e = 0.0
    for _ in range(max_iter):
        mid = 0.5 * (a + b)
        tol1 = sqrt_eps * abs(x) + xtol / 3.0
        tol2 = 2.0 * tol1
        if abs(x - mid) <= tol2 - 0.5 * (b - a):
            break
        parabolic = False
        if abs(e) > tol1 and np.isfinite(fx) and np.isfinite(fw) and np.isfinite(fv):
            r = (x - w) * (fx - fv)
            q = (x - v) * (fx - fw)
            p = (x - v) * q - (x - w) * r
            q = 2.0 * (q - r)
            if q > 0.0:
                p = -p
            q = abs(q)
            if abs(p) < abs(0.5 * q * e) and q * (a - x) < p < q * (b - x):
                e, d = d, p / q
                parabolic = True
                if (x + d) - a < tol2 or b - (x + d) < tol2:
                    d = tol1 if x < mid else -tol1
        if not parabolic:
            e = (b - x) if x < mid else (a - x)
            d = golden * e
        u = x + (d if abs(d) >= tol1 else (tol1 if d > 0 else -tol1))
        fu = f(u)
        if fu <= fx:
            if u < x:
                b = x
            else:
                a = x
            v, fv, w, fw, x, fx = w, fw, x, fx, u, fu
        else:
            if u < x:
                a = u
            else:
                b = u
            if fu <= fw or w == x:
                v, fv, w, fw = w, fw, u, fu
            elif fu <= fv or v == x or v == w:
                v, fv = u, fu
    return x, fx
