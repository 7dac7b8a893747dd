"""Bracketed root finding and bounded minimisation for the small noise-model fits, numpy only.

The IEEE 952 fit searches its profiles and quantization ratio hundreds of times per channel;
scipy.optimize would do it, but importing it costs ~0.5 s of CPU, more than the whole
``workbench allan`` analysis of a 1e6-sample record. Both algorithms are textbook (the fit's
non-negative least squares are compiled: :mod:`workbench.analysis.allan_fit_kernels`):

* :func:`root_bracket`: the Illinois variant of regula falsi (Dowell & Jarratt 1971), which keeps
  the bracket and converges superlinearly.
* :func:`minimize_bounded`: Brent's minimiser on an interval (golden section with parabolic
  steps; Brent, *Algorithms for Minimization without Derivatives* (1973), ch. 5, the algorithm
  of scipy.optimize.fminbound).

They are tested against scipy.optimize.brentq / minimize_scalar (tests/analysis/test_small_solvers.py).

Public: :func:`root_bracket`, :func:`minimize_bounded`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


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
