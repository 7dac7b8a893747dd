"""Compiled (numba) kernels of the total and Theo statistics of :mod:`workbench.analysis.stability`.

Loaded only when one of them runs (numba's start-up, ~0.4 s of CPU, is paid by those statistics
alone; the registry is loaded as :mod:`workbench.analysis.allan_kernels` does, without scipy).

Public: :func:`mtot_sum`, :func:`reflected`, :func:`totdev_sum`, :func:`theo1_sum`.
"""

from __future__ import annotations

import numba
import numpy as np

import workbench.analysis.allan_kernels  # noqa: F401  (numba's array registry without scipy's BLAS probe)


@numba.njit(cache=True, nogil=True)
def mtot_sum(x, m, hadamard):  # pragma: no cover - compiled
    """Sum over subsequences of 3m points of the mean squared second difference of m-point sums
    of the half-average-detrended, evenly reflected (9m) subsequence (SP 1065 eq. 27; Stable32).

    ``hadamard``: x is frequency data (the Hadamard total; slope per sample, centred index),
    otherwise phase (modified total), divided by m^2 as mdev's inner sums.
    """
    n = x.shape[0]
    total = 0.0
    three = 3 * m
    h1 = three // 2
    h2 = (three + 1) // 2
    dist = (0.5 * (three - 1) + 1.0) if three % 2 == 1 else 0.5 * three
    star = np.empty(9 * m)
    for i in range(n - three + 1):
        mean1 = 0.0
        for j in range(h1):
            mean1 += x[i + j]
        mean1 /= h1
        mean2 = 0.0
        for j in range(h2, three):
            mean2 += x[i + j]
        mean2 /= three - h2
        slope = (mean2 - mean1) / dist
        for j in range(three):
            v = x[i + j] - slope * ((j - h1) if hadamard else j)
            star[three + j] = v
            star[three - 1 - j] = v
            star[3 * three - 1 - j] = v
        s1 = 0.0
        s2 = 0.0
        s3 = 0.0
        for j in range(m):
            s1 += star[j]
            s2 += star[m + j]
            s3 += star[2 * m + j]
        acc = 0.0
        for j in range(6 * m):
            if j > 0:
                s1 += star[j + m - 1] - star[j - 1]
                s2 += star[j + 2 * m - 1] - star[m + j - 1]
                s3 += star[j + 3 * m - 1] - star[2 * m + j - 1]
            d = (s1 - 2.0 * s2 + s3) / m
            acc += d * d
        total += acc / (6.0 * m) / (6.0 if hadamard else 1.0)  # Hadamard: 1/6 <(second diff)^2>
    return total


@numba.njit(cache=True, nogil=True)
def reflected(x, k):  # pragma: no cover - compiled
    """Point k of the phase extended by odd reflection at both ends (SP 1065 eq. 25): x[k] inside,
    2 x[0] - x[-k] before the start, 2 x[L-1] - x[2L-2-k] after the end."""
    n = x.shape[0]
    if k < 0:
        return 2.0 * x[0] - x[-k]
    if k >= n:
        return 2.0 * x[n - 1] - x[2 * n - 2 - k]
    return x[k]


@numba.njit(cache=True, nogil=True)
def totdev_sum(x, m):  # pragma: no cover - compiled
    """Total-deviation sum over the centres x_1 .. x_{L-2} of (x*[t-m] - 2 x[t] + x*[t+m])^2, x* the
    reflected extension (:func:`reflected`), in one pass, partial sums of 4096 terms."""
    n = x.shape[0]
    total = 0.0
    for b0 in range(1, n - 1, 4096):
        part = 0.0
        for t in range(b0, min(b0 + 4096, n - 1)):
            d = reflected(x, t - m) - 2.0 * x[t] + reflected(x, t + m)
            part += d * d
        total += part
    return total


@numba.njit(cache=True, nogil=True)
def theo1_sum(x, m):  # pragma: no cover - compiled
    """Theo1 double sum (SP 1065 eq. 30) for even m."""
    n = x.shape[0]
    h = m // 2
    total = 0.0
    for i in range(n - m):
        s = 0.0
        for d in range(h):
            v = x[i] - x[i - d + h] + x[i + m] - x[i + d + h]
            s += v * v / (h - d)
        total += s
    return total
