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


@pytest.mark.parametrize("piece_rows", [1 << 20, 64])
def test_parquet_row_groups_and_pieces_give_the_whole_record(tmp_path, monkeypatch, piece_rows):
    """Row groups read whole, or (groups larger than PIECE_ROWS) batches: the same samples and time,
    in a rate buffer whose phase can be integrated in place."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from workbench.analysis.allan import phase
    from workbench.cli import allan_record

    monkeypatch.setattr(allan_record, "PIECE_ROWS", piece_rows)
    rng = np.random.default_rng(3)
    t, gx, gz = np.arange(1000) / 100.0, rng.standard_normal(1000), rng.integers(-5, 5, 1000)
    pq.write_table(pa.table({"t": t, "gx": gx, "gz": gz}), tmp_path / "r.parquet", row_group_size=300)
    y, rate, cols, _ = load_record(tmp_path / "r.parquet", None, None)
    assert cols == ["gx", "gz"] and rate == pytest.approx(100.0)
    assert np.array_equal(y, np.column_stack([gx, gz]))
    expected = phase(y.copy(), rate)
    x = phase(y, rate, overwrite=True)
    assert np.shares_memory(x, y) and np.array_equal(x, expected)
