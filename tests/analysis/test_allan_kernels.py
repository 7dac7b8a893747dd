"""The compiled Allan kernels (workbench/analysis/allan_kernels.py) against plain numpy sums.

Each kernel is a sum of floating-point terms; numpy sums the same terms in another order, so the
two agree to the rounding of the sum: relative ~ eps sqrt(N) (pairwise vs blocked), 1e-10 used
(N <= 1e5, eps sqrt(N) ~ 7e-14; the margin covers cancellation in the differences of a phase
that grows as a random walk).
"""

import numpy as np
import pytest

from workbench.analysis import allan_kernels as ak

RTOL = 1e-10


def _rate(n: int, c: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return 1e-3 + rng.normal(0.0, 1e-4, (n, c))  # rad/s-sized rates with a bias


def test_column_sums_equal_numpy_sum_across_blocks():
    y = _rate(3 * ak.BLOCK + 17, 3, 1)  # several blocks plus a partial one
    np.testing.assert_allclose(ak.column_sums(y), y.sum(axis=0), rtol=RTOL)


def test_integrate_is_dt_cumsum_of_the_demeaned_rate_and_chunks_carry():
    y = _rate(10_000, 3, 2)
    dt = 0.01
    mean = y.mean(axis=0)
    ref = (np.cumsum(y - mean, axis=0) * dt).T
    whole = np.empty((3, len(y)))
    ak.integrate(y, mean, dt, np.zeros(3), whole)
    np.testing.assert_allclose(whole, ref, rtol=RTOL, atol=RTOL * np.abs(ref).max())
    # the same record in two chunks, the running sum carried between them
    run = np.zeros(3)
    parts = []
    for chunk in (y[:3333], y[3333:]):
        out = np.empty((3, len(chunk)))
        ak.integrate(chunk, mean, dt, run, out)
        parts.append(out)
    np.testing.assert_allclose(np.hstack(parts), ref, rtol=RTOL, atol=RTOL * np.abs(ref).max())


def _phase(n: int, c: int, seed: int) -> np.ndarray:
    y = _rate(n, c, seed)
    return np.ascontiguousarray((np.cumsum(y - y.mean(axis=0), axis=0) * 0.01).T)


@pytest.mark.parametrize("order", [2, 3])
def test_diff_sums_are_the_sums_of_squared_differences(order):
    x = _phase(20_000, 2, 3)
    n = x.shape[1]
    lags = np.array([1, 2, 7, 64, 1000, 3000], np.int64)
    i0 = np.array([0, 5, 0, 100, 0, 2], np.int64)  # sub-ranges: a caller sums a record in pieces
    i1 = np.array([n - order * m for m in lags], np.int64)
    i1[1] -= 4000
    out = np.zeros((len(lags), 2))
    ak.diff_sums(x, lags, order, i0, i1, out)
    for j, m in enumerate(lags):
        for c in range(2):
            xs = x[c]
            idx = np.arange(i0[j], i1[j])
            if order == 2:
                d = xs[idx + 2 * m] - 2 * xs[idx + m] + xs[idx]
            else:
                d = xs[idx + 3 * m] - 3 * xs[idx + 2 * m] + 3 * xs[idx + m] - xs[idx]
            assert out[j, c] == pytest.approx(np.sum(d * d), rel=RTOL), (m, c)


def test_mdev_sums_are_the_squared_inner_sums_of_the_modified_allan_variance():
    """v_j = sum_{i=j}^{j+m-1} (x[i+2m] - 2 x[i+m] + x[i]); the kernel returns sum_j v_j^2 (state: v_0, run 0)."""
    x = _phase(12_000, 2, 4)
    n = x.shape[1]
    lags = np.array([1, 3, 16, 500], np.int64)
    k_n = len(lags)
    j0 = np.zeros(k_n, np.int64)
    j1 = np.array([n - 3 * m + 1 for m in lags], np.int64)
    ref = np.zeros((k_n, 2))
    v0 = np.zeros((k_n, 2))
    for k, m in enumerate(lags):
        for c in range(2):
            d2 = x[c, 2 * m:] - 2 * x[c, m:-m] + x[c, :-2 * m]  # second differences, len n - 2m
            v = np.convolve(d2, np.ones(m), "valid")  # inner sums over m consecutive i
            ref[k, c] = np.sum(v[:j1[k]] ** 2)
            v0[k, c] = v[0]
    out = np.zeros((k_n, 2))
    ak.mdev_sums(x, lags, j0, j1, v0, np.zeros((k_n, 2)), out)
    np.testing.assert_allclose(out, ref, rtol=RTOL)
    # split at j = 5000: the second call continues from the state the first left
    run = np.zeros((k_n, 2))
    out2 = np.zeros((k_n, 2))
    mid = np.minimum(5000, j1)
    ak.mdev_sums(x, lags, j0, mid, v0, run, out2)
    ak.mdev_sums(x, lags, mid, j1, v0, run, out2)
    np.testing.assert_allclose(out2, ref, rtol=RTOL)
