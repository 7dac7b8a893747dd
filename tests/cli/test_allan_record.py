"""Reading the record of ``workbench allan`` (workbench.cli.allan_record): rate, gaps, one-line errors."""

import numpy as np
import pandas as pd
import pytest

from workbench.cli.allan_record import load_record, quantity_of, rate_from_time
from workbench.errors import AnalysisError


def test_rate_and_gaps_from_a_time_column():
    t = np.arange(100) / 50.0
    t[60:] += 0.1  # five intervals missing after row 59
    rate, gaps = rate_from_time(t, "f.csv")
    assert rate == pytest.approx(50.0) and gaps.tolist() == [59]
    jitter = np.arange(100) / 50.0
    jitter[10] += 0.005  # 25 % of an interval either side of row 10: beyond the 1 % tolerance, not a gap
    with pytest.raises(AnalysisError, match=r"f.csv: non-constant sample rate: interval .* at row 1[01] "):
        rate_from_time(jitter, "f.csv")


def test_a_csv_gap_becomes_nan_rows_and_columns_are_checked(tmp_path):
    t = np.arange(200) / 100.0
    t[100:] += 0.05
    pd.DataFrame({"t": t, "gx": 1.0, "gy": 2.0, "step": 0}).to_csv(tmp_path / "r.csv", index=False)
    y, rate, cols, label = load_record(tmp_path / "r.csv", None, None)
    assert cols == ["gx", "gy"] and rate == pytest.approx(100.0) and label == str(tmp_path / "r.csv")
    assert y.shape == (201, 2) and np.isnan(y[100]).all() and np.isfinite(np.delete(y, 100, axis=0)).all()
    with pytest.raises(AnalysisError, match=r"r.csv: no column\(s\) gz"):
        load_record(tmp_path / "r.csv", ["gz"], None)
    assert quantity_of(["gx", "gy"]) == "gyro" and quantity_of(["ax"]) == "accel" and quantity_of(["gx", "ax"]) is None


def test_a_text_file_needs_the_rate_and_numbers(tmp_path):
    (tmp_path / "d.txt").write_text("# header\n1.0\n\n2.5 extra\n")
    y, rate, cols, _ = load_record(tmp_path / "d.txt", None, 10.0)
    assert y[:, 0].tolist() == [1.0, 2.5] and rate == 10.0 and cols == ["data"]
    with pytest.raises(AnalysisError, match="give the sample rate with --rate"):
        load_record(tmp_path / "d.txt", None, None)
    (tmp_path / "d.txt").write_text("1\nx\n")
    with pytest.raises(AnalysisError, match="line 2: 'x' is not a number"):
        load_record(tmp_path / "d.txt", None, 10.0)


def test_parquet_read_by_column_equals_the_csv_path(tmp_path):
    rng = np.random.default_rng(2)
    df = pd.DataFrame({"t": np.arange(300) / 100.0, "ax": rng.standard_normal(300), "ay": rng.standard_normal(300)})
    df.to_parquet(tmp_path / "r.parquet")
    df.to_csv(tmp_path / "r.csv", index=False)
    yp, rp, cp, _ = load_record(tmp_path / "r.parquet", None, None)
    yc, rc, cc, _ = load_record(tmp_path / "r.csv", None, None)
    assert cp == cc == ["ax", "ay"] and rp == pytest.approx(rc) and np.array_equal(yp, yc)
