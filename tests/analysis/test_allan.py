"""Overlapping ADEV, MDEV and overlapping HDEV against allantools (the oracle), and bad input.

allantools computes the same estimators with plain numpy on the same phase construction
(x_0 = 0, x = dt cumsum(y - mean)); only the summation order differs, so the relative
difference is at the level of eps * sqrt(N) ~ 1e-13, far inside the 1e-9 required.
"""

import allantools
import numpy as np
import pytest

from workbench.analysis.allan import averaging_factors, deviation
from workbench.errors import AnalysisError

RATE = 100.0


def _record(n: int, seed: int) -> np.ndarray:
    """White + random-walk rate noise on a large offset (3 channels), rad/s."""
    rng = np.random.default_rng(seed)
    return 0.3 + 1e-3 * rng.standard_normal((n, 3)) + 1e-6 * np.cumsum(rng.standard_normal((n, 3)), axis=0)


@pytest.mark.parametrize("kind", ["oadev", "mdev", "ohdev"])
@pytest.mark.parametrize("taus", ["octave", "decade", "7-per-decade"])
def test_equals_allantools(kind, taus):
    y = _record(30_000, 1)
    curve = deviation(y, RATE, kind, taus)
    for c in range(3):
        t, dev, _, n = getattr(allantools, kind)(np.ascontiguousarray(y[:, c]), RATE, "freq", curve.tau)
        np.testing.assert_array_equal(n, curve.n)
        np.testing.assert_allclose(t, curve.tau, rtol=1e-15)
        np.testing.assert_allclose(curve.dev[:, c], dev, rtol=1e-9, atol=0)


@pytest.mark.parametrize("grid", ["octave", "decade"])
def test_tau_grids_equal_allantools(grid):
    y = _record(12_345, 2)[:, 0]
    t, *_ = allantools.oadev(y, RATE, "freq", grid)
    np.testing.assert_allclose(deviation(y, RATE, "oadev", grid).tau, t, rtol=1e-15)


def test_per_decade_grid_density():
    m = averaging_factors(1_000_001, "10-per-decade", 1.0)
    per_decade = np.histogram(np.log10(m), bins=np.arange(0, 7))[0]
    # 10 log-spaced points per decade (+-1 from where the bin edges fall); the first decade
    # rounds to fewer distinct integers and the last ends at m = N/2 (oadev needs n >= 2)
    assert np.all((per_decade[1:5] >= 9) & (per_decade[1:5] <= 11)), per_decade


def test_split_gap_policy_pools_the_runs():
    # Two runs separated by NaNs: the pooled AVAR is (S1 + S2) / (2 tau^2 (n1 + n2)) where each
    # run's sum S_k = 2 tau^2 n_k AVAR_k comes from allantools on that run alone.
    y = _record(20_000, 3)
    y[8_000:8_010] = np.nan
    runs = [y[:8_000], y[8_010:]]
    curve = deviation(y, RATE, "oadev", "octave", gap_policy="split")
    s, n = 0.0, 0
    for r in runs:
        t, dev, _, nk = allantools.oadev(np.ascontiguousarray(r[:, 1]), RATE, "freq", curve.tau)
        keep = np.isin(curve.tau, t)
        s_k = np.zeros(len(curve.tau))
        n_k = np.zeros(len(curve.tau))
        s_k[keep] = 2 * t ** 2 * nk * dev ** 2
        n_k[keep] = nk
        s, n = s + s_k, n + n_k
    np.testing.assert_array_equal(n, curve.n)
    np.testing.assert_allclose(curve.dev[:, 1], np.sqrt(s / (2 * curve.tau ** 2 * n)), rtol=1e-9)


def test_longest_gap_policy_uses_longest_run():
    y = _record(20_000, 4)
    y[5_000] = np.nan
    curve = deviation(y, RATE, "oadev", gap_policy="longest")
    t, dev, *_ = allantools.oadev(np.ascontiguousarray(y[5_001:, 0]), RATE, "freq", "octave")
    np.testing.assert_allclose(curve.dev[:, 0], dev, rtol=1e-9)
    assert curve.n_samples == 20_000 - 5_001


def test_nan_is_reported_not_dropped():
    y = _record(5_000, 5)
    y[1234:1240, 2] = np.nan
    with pytest.raises(AnalysisError, match=r"column gz: 6 NaN.*rows 1234-1239"):
        deviation(y, RATE, columns=["gx", "gy", "gz"])


def test_too_few_samples():
    with pytest.raises(AnalysisError, match="at least 100"):
        deviation(np.zeros((99, 3)), RATE)


def test_deg_per_s_declared_as_rad_per_s():
    # a static gyro whose bias is 2 deg/s reads 2 "rad/s" when degrees are declared as radians
    y = 2.0 + 0.01 * np.random.default_rng(6).standard_normal((1_000, 3))
    with pytest.raises(AnalysisError, match="deg/s declared as rad/s"):
        deviation(y, RATE, quantity="gyro", columns=["gx", "gy", "gz"])


def test_bad_tau_grid_and_kind():
    y = _record(1_000, 7)
    with pytest.raises(AnalysisError, match="per-decade"):
        deviation(y, RATE, taus="many")
    with pytest.raises(AnalysisError, match="kind"):
        deviation(y, RATE, kind="totdev")


@pytest.mark.parametrize("kind", ["oadev", "ohdev"])
def test_numpy_and_compiled_kernels_agree(kind):
    # short records run the numpy sums, long ones the numba kernels (allan.COMPILED_WORK): both
    # paths, forced on the same record, against allantools on every channel
    from workbench.analysis.allan import ORDER, normalise, phase, squared_sums

    y = _record(20_000, 4)
    m = averaging_factors(len(y) + 1, "octave", RATE, kind)
    n = len(y) + 1 - ORDER[kind] * m
    for compiled in (False, True):
        x = phase(y, RATE, compiled=compiled)
        dev = normalise(kind, squared_sums(x, m, kind, compiled=compiled), n, m, RATE)
        for c in range(3):
            _, ref, _, _ = getattr(allantools, kind)(np.ascontiguousarray(y[:, c]), RATE, "freq", m / RATE)
            np.testing.assert_allclose(dev[:, c], ref, rtol=1e-9, atol=0)


def test_channel_major_record_gives_the_same_curve():
    # the CLI reads a Parquet file channel by channel into a (C, N) array and passes its (N, C)
    # view (F-ordered): same phase, same deviation as the row-major record
    y = _record(50_000, 6)
    yf = np.asfortranarray(y)
    from workbench.analysis.allan import phase

    np.testing.assert_array_equal(phase(yf, RATE), phase(y, RATE, compiled=False))
    np.testing.assert_allclose(deviation(yf, RATE).dev, deviation(y, RATE).dev, rtol=1e-12)


def test_phase_in_place_of_a_rate_buffer_equals_the_copy(monkeypatch):
    """``overwrite`` integrates into the buffer only for the exact ``buf[:, 1:].T`` view."""
    from workbench.analysis import allan
    from workbench.analysis.allan import phase, rate_buffer

    y = np.random.default_rng(4).standard_normal((500, 3))
    expected = phase(y, 10.0)
    for populate in (0, 1 << 62):  # a mapped buffer, and np.empty
        monkeypatch.setattr(allan, "POPULATE_BYTES", populate)
        buf = rate_buffer(500, 3)
        buf[:, 1:] = y.T
        x = phase(buf[:, 1:].T, 10.0, overwrite=True)
        assert np.shares_memory(x, buf) and x.shape == buf.shape and np.array_equal(x, expected)
    other = rate_buffer(500, 3)
    other[:, 1:] = y.T
    part = other[:, 1:-1].T  # not the whole buffer: a new array, the samples untouched
    x = phase(part, 10.0, overwrite=True)
    assert not np.shares_memory(x, other) and np.array_equal(other[:, 1:], y.T)
