"""Streaming deviations (Parquet or any batch source) and the streamed analysis equal the in-memory ones.

Small row groups, batches, blocks and window force every code path (carried running sum
across batches, shared-window lags, split-read long lags) on a file that also fits in memory.
"""

import allantools
import numpy as np
import pandas as pd
import pytest

from workbench.analysis.allan import deviation, phase
from workbench.analysis.allan_fit import TERMS, analyze_record, analyze_stream
from workbench.analysis.allan_stream import stream_deviation, stream_deviation_from
from workbench.errors import AnalysisError


@pytest.fixture()
def parquet(tmp_path):
    rng = np.random.default_rng(21)
    n = 120_000
    y = 0.01 + 1e-3 * rng.standard_normal((n, 2)) + 1e-6 * np.cumsum(rng.standard_normal((n, 2)), axis=0)
    path = tmp_path / "rates.parquet"
    pd.DataFrame(y, columns=["gx", "gy"]).to_parquet(path, row_group_size=25_000)
    return path, y


@pytest.mark.parametrize("kind", ["oadev", "ohdev"])
def test_stream_equals_in_memory_and_allantools(parquet, kind):
    path, y = parquet
    s = stream_deviation(path, ["gx", "gy"], 100.0, kind, "9-per-decade", rows=7_000, block=5_000, window=3_000)
    m = deviation(y, 100.0, kind, "9-per-decade")
    np.testing.assert_array_equal(s.m, m.m)
    np.testing.assert_array_equal(s.n, m.n)
    assert np.any(s.m * 3 > 3_000)  # some lags take the split-read path
    np.testing.assert_allclose(s.dev, m.dev, rtol=1e-9)
    _, ref, *_ = getattr(allantools, kind)(np.ascontiguousarray(y[:, 1]), 100.0, "freq", s.tau)
    np.testing.assert_allclose(s.dev[:, 1], ref, rtol=1e-9)


def test_stream_reports_nan_row_and_missing_column(tmp_path):
    y = np.random.default_rng(22).standard_normal((5_000, 1))
    y[3_210] = np.nan
    path = tmp_path / "bad.parquet"
    pd.DataFrame(y, columns=["az"]).to_parquet(path, row_group_size=1_000)
    with pytest.raises(AnalysisError, match="column az: NaN or infinite value at row 3210"):
        stream_deviation(path, ["az"], 100.0, rows=700)
    with pytest.raises(AnalysisError, match="no column"):
        stream_deviation(path, ["gx"], 100.0)
    with pytest.raises(AnalysisError, match="streaming supports"):
        stream_deviation(path, ["az"], 100.0, kind="mdev")


def test_streamed_analysis_equals_in_memory():
    """analyze_stream keeps exactly the decimated phase points the in-memory noise identification
    reads (the first MAX_POINTS_ID of x[::m]); with 150k samples > MAX_POINTS_ID and batches of a
    size prime to every m, the cap and the batch boundaries are both exercised. The deviations
    differ only by summation order (~1e-14 measured), so the identified exponents and EDFs must
    be identical and every derived number (intervals, fitted terms, their intervals) equal to a
    relative 1e-9: the IRLS fit stops at a 1e-8 relative step, far above a 1e-14 input change,
    so both runs take the same iterations and stay within rounding of each other."""
    rng = np.random.default_rng(3)
    n, rows = 150_000, 7_001
    y = 0.01 + 1e-3 * rng.standard_normal((n, 3)) + 2e-6 * np.cumsum(rng.standard_normal((n, 3)), axis=0)
    cols = ["gx", "gy", "gz"]
    mem = analyze_record(y, 100.0, cols, "gyro")
    st = analyze_stream(lambda: (y[i:i + rows] for i in range(0, n, rows)), 100.0, cols, "gyro")
    np.testing.assert_array_equal(st.ci.curve.m, mem.ci.curve.m)
    np.testing.assert_allclose(st.ci.curve.dev, mem.ci.curve.dev, rtol=1e-12)
    np.testing.assert_array_equal(st.ci.alpha, mem.ci.alpha)
    np.testing.assert_array_equal(st.ci.edf, mem.ci.edf)
    np.testing.assert_allclose(np.stack([st.ci.lo, st.ci.hi]), np.stack([mem.ci.lo, mem.ci.hi]), rtol=1e-12)
    for fs, fm in zip(st.fits, mem.fits):
        for name in TERMS:
            a, b = fs.terms[name], fm.terms[name]
            assert a.observed == b.observed
            np.testing.assert_allclose([a.value, *a.ci95], [b.value, *b.ci95], rtol=1e-9)
    assert {f.terms["white"].observed for f in st.fits} == {True}


def test_streamed_decimation_matches_phase():
    """The kept points are the in-memory phase decimated by m (exact up to the mean's summation order)."""
    y = np.random.default_rng(4).standard_normal((1_000, 2))
    s = stream_deviation_from(lambda: (y[i:i + 97] for i in range(0, 1_000, 97)), ["a", "b"], 10.0, keep=40)
    x = phase(y, 10.0)
    for mk, z in zip(s.curve.m, s.decimated):
        np.testing.assert_allclose(z, x[:, ::mk][:, :40], rtol=0, atol=1e-12)


def test_stream_from_checks_magnitude_and_shape():
    y = np.full((2_000, 3), 0.02)  # 0.02 rad/s is fine; x 60 (deg/s declared as rad/s) is not
    with pytest.raises(AnalysisError, match="column gx: median 1.2 rad/s is implausible"):
        stream_deviation_from(lambda: iter([60 * y]), ["gx", "gy", "gz"], 100.0, quantity="gyro")
    with pytest.raises(AnalysisError, match="does not match columns"):
        stream_deviation_from(lambda: iter([y]), ["gx", "gy"], 100.0)
