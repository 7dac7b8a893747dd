"""Compiled (numba) kernels of the Allan deviations: long records, every lag in one pass.

Loaded only when a record is long enough for the compiled sums to repay numba's start-up
(about 0.5 s of CPU to import numba and load the cached kernels), by
:func:`workbench.analysis.allan.squared_sums` and :func:`workbench.analysis.allan.phase`, and by
the streamed path (:mod:`workbench.analysis.allan_stream`). The sums equal allantools'
``oadev``/``ohdev``/``mdev`` to a relative 1e-9 (tests/analysis/test_allan.py).

Public: :func:`column_sums`, :func:`integrate`, :func:`block_sum`, :func:`diff_sums`, :func:`mdev_sums`.
"""

from __future__ import annotations

import sys

import numba
import numpy as np


def _load_numba_np() -> None:
    """Import numba's array registry with scipy hidden: its BLAS probe imports scipy.linalg
    (~0.3 s of CPU, a third of numba's start-up) and these kernels use no BLAS. Only numba's
    ``np.correlate`` / ``np.convolve`` then use their loop (matrix products still find scipy's
    BLAS when compiled: the module is visible again as soon as the registry is loaded)."""
    hide = "scipy.linalg" if "scipy" in sys.modules else "scipy"
    if "numba.np.arraymath" in sys.modules or hide in sys.modules:
        return
    sys.modules[hide] = None  # type: ignore[assignment]  # import of it raises ImportError
    try:
        import numba.np.arraymath  # noqa: F401
    finally:
        del sys.modules[hide]


_load_numba_np()

BLOCK = 4096  # phase points per cache block (x 8 bytes x up to 4 lag windows: fits L2)


@numba.njit(cache=True, nogil=True)
def column_sums(y):  # pragma: no cover - compiled
    """Column sums (C,) of y (N, C), accumulated in blocks (error ~ eps sqrt(N / block))."""
    total = np.zeros(y.shape[1])
    for b0 in range(0, y.shape[0], BLOCK):
        part = np.zeros(y.shape[1])
        for k in range(b0, min(b0 + BLOCK, y.shape[0])):
            for c in range(y.shape[1]):
                part[c] += y[k, c]
        total += part
    return total


@numba.njit(cache=True, nogil=True)
def integrate(y, mean, dt, run, x):  # pragma: no cover - compiled
    """x[c, k] = dt * (run[c] + sum_{i<=k} (y[i, c] - mean[c])), in one pass.

    The running sum is kept unscaled and multiplied by dt per point, the order of operations
    of ``cumsum(y - mean) * dt`` (allantools). ``run`` (C,) carries the unscaled running sum
    from the previous chunk of a record (zeros for the first) and is updated in place.
    """
    n_ch = y.shape[1]
    for k in range(y.shape[0]):
        for c in range(n_ch):
            run[c] += y[k, c] - mean[c]
            x[c, k] = run[c] * dt


@numba.njit(cache=True, nogil=True, fastmath=True, error_model="numpy", boundscheck=False)
def block_sum(x0, x1, x2, x3, order):  # pragma: no cover - compiled
    """Sum of squared order-th differences of aligned windows x0..x3 (x[i], x[i+m], ...; x3 unused for order 2)."""
    acc = 0.0
    if order == 2:
        for i in range(x0.shape[0]):
            d = x2[i] - 2.0 * x1[i] + x0[i]
            acc += d * d
    else:
        for i in range(x0.shape[0]):
            d = x3[i] - 3.0 * x2[i] + 3.0 * x1[i] - x0[i]
            acc += d * d
    return acc


@numba.njit(cache=True, nogil=True, error_model="numpy", boundscheck=False)
def diff_sums(x, lags, order, i0, i1, out):  # pragma: no cover - compiled
    """out[j, c] += sum over i in [i0[j], i1[j]) of (order-th difference of x[c] at lag lags[j], at i)^2.

    Channel by channel, the index range is walked in blocks of ``BLOCK`` and every lag is
    summed per block, so a phase window loaded for one lag (x[i+m] of lag m is x[i+2m] of
    lag m/2) is reused from cache by the others.
    """
    lo = i0.min()
    hi = i1.max()
    for c in range(x.shape[0]):
        xc = x[c]
        for b0 in range(lo, hi, BLOCK):
            b1 = min(b0 + BLOCK, hi)
            for j in range(lags.shape[0]):
                m = lags[j]
                s0 = max(b0, i0[j])
                s1 = min(b1, i1[j])
                if s1 > s0:
                    out[j, c] += block_sum(xc[s0:s1], xc[s0 + m:s1 + m], xc[s0 + 2 * m:s1 + 2 * m],
                                            xc[s0 + order * m:s1 + order * m], order)


@numba.njit(cache=True, nogil=True)
def mdev_sums(x, lags, j0, j1, v0, run, out):  # pragma: no cover - compiled
    """Modified-Allan sums by allantools' recursion (same order of operations).

    For lag m the inner sum at j is v_j = v0 + run_j, run_j = run_{j-1} + (x[j+3m-1] - 3x[j+2m-1]
    + 3x[j+m-1] - x[j-1]); j runs over [j0[k], j1[k]) (j = 0 is the first term, v0 its value).
    ``v0``, ``run`` (K, C) hold the state; ``out`` (K, C) accumulates v_j^2 in blocks of
    ``BLOCK`` terms from j0. Channels advance three at a time (:func:`_mdev_three`): their
    recursions are independent chains the processor overlaps, where one alone waits on each addition.
    """
    n_ch = x.shape[0]
    for k in range(lags.shape[0]):
        for c in range(0, n_ch, 3):
            a, b, d = c, min(c + 1, n_ch - 1), min(c + 2, n_ch - 1)  # a short group repeats its last channel
            ra, rb, rd, sa, sb, sd = _mdev_three(x[a], x[b], x[d], lags[k], j0[k], j1[k], run[k, a], run[k, b],
                                                 run[k, d], v0[k, a], v0[k, b], v0[k, d])
            run[k, a], run[k, b], run[k, d] = ra, rb, rd
            out[k, a] += sa
            if b != a:
                out[k, b] += sb
            if d != b:
                out[k, d] += sd


@numba.njit(cache=True, nogil=True, error_model="numpy", boundscheck=False)
def _mdev_three(xa, xb, xd, m, j_start, j_stop, ra, rb, rd, va, vb, vd):  # pragma: no cover - compiled
    """:func:`mdev_sums` of one lag for three channels: (running sums, sums of v^2 per channel)."""
    ta = tb = td = 0.0
    for b0 in range(j_start, j_stop, BLOCK):
        b1 = min(b0 + BLOCK, j_stop)
        qa = qb = qd = 0.0
        start = b0
        if b0 == 0:
            qa, qb, qd = va * va, vb * vb, vd * vd
            start = 1
        for j in range(start, b1):
            ra += xa[j + 3 * m - 1] - 3.0 * xa[j + 2 * m - 1] + 3.0 * xa[j + m - 1] - xa[j - 1]
            rb += xb[j + 3 * m - 1] - 3.0 * xb[j + 2 * m - 1] + 3.0 * xb[j + m - 1] - xb[j - 1]
            rd += xd[j + 3 * m - 1] - 3.0 * xd[j + 2 * m - 1] + 3.0 * xd[j + m - 1] - xd[j - 1]
            wa, wb, wd = va + ra, vb + rb, vd + rd
            qa += wa * wa
            qb += wb * wb
            qd += wd * wd
        ta += qa
        tb += qb
        td += qd
    return ra, rb, rd, ta, tb, td
