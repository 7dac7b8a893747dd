"""Streaming deviations from Parquet equal the in-memory ones and allantools.

Small row groups, batches, blocks and window force every code path (carried running sum
across batches, shared-window lags, split-read long lags) on a file that also fits in memory.
"""

import allantools
import numpy as np
import pandas as pd
import pytest

from workbench.analysis.allan import deviation
from workbench.analysis.allan_stream import stream_deviation
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
