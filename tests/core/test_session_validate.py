"""Sample validation (workbench.session_validate) on synthetic tables: in memory and batch by batch."""

import numpy as np
import pandas as pd
import pytest

from workbench.errors import SessionError
from workbench.session_types import StepRecord
from workbench.session_validate import validate_parquet_stream, validate_samples

RATE = 100.0


def _table(n=400, gap_at=None, accel_scale=1.0):
    """Two static steps of n / 2 samples at 100 Hz, gyro 1e-3 rad/s noise, accel (0, 0, -9.81) m/s^2."""
    rng = np.random.default_rng(5)
    t = np.arange(n) / RATE
    if gap_at is not None:
        t[gap_at:] += 0.5  # 50 sample intervals missing
    df = pd.DataFrame({"t": t, "step": (np.arange(n) >= n // 2).astype(int)})
    for c in ("gx", "gy", "gz"):
        df[c] = 1e-3 * rng.standard_normal(n)
    df["ax"], df["ay"], df["az"] = 0.0, 0.0, -9.81 * accel_scale
    return df


def _steps(df):
    t, lab = df["t"].to_numpy(), df["step"].to_numpy()
    return [StepRecord(i, "static", float(t[lab == i][0]), float(t[lab == i][-1]) + 1 / RATE) for i in (0, 1)]


def test_a_good_table_passes_and_a_gap_between_steps_is_allowed():
    df = _table(gap_at=200)  # the pause falls exactly where step 1 begins
    assert validate_samples(df, _steps(df), RATE, "s.parquet") is df


@pytest.mark.parametrize("edit,match", [
    (lambda df: df.drop(columns="gy"), "missing column"),
    (lambda df: df.assign(gx=np.where(np.arange(len(df)) == 7, np.nan, df["gx"])), "column gx: NaN .* row 7"),
    (lambda df: df.assign(az=df["az"] / 9.81), "columns ax, ay, az: median"),  # accel in g
    (lambda df: df.assign(gx=df["gx"] + 100.0), "columns gx, gy, gz"),  # gyro in deg/s
])
def test_errors_name_the_file_and_column(edit, match):
    df = _table()
    with pytest.raises(SessionError, match=match) as e:
        validate_samples(edit(df), _steps(df), RATE, "s.parquet")
    assert str(e.value).startswith("s.parquet: ")


def test_a_gap_inside_a_step_names_the_step_unless_allowed():
    df = _table(gap_at=100)
    steps = _steps(df)
    with pytest.raises(SessionError, match="step 0: column t: gap of 0.51 s"):
        validate_samples(df, steps, RATE, "s.parquet")
    validate_samples(df, steps, RATE, "s.parquet", gaps_in_steps=True)


def test_a_rate_off_the_time_column_names_both():
    df = _table()
    with pytest.raises(SessionError, match="sample_rate_hz 50 Hz disagrees with column t.*100 Hz"):
        validate_samples(df, _steps(df), 50.0, "s.parquet")


def test_the_stream_check_agrees_with_the_in_memory_one_across_batch_boundaries(tmp_path):
    good, gapped = _table(), _table(gap_at=130)
    good.to_parquet(tmp_path / "good.parquet")
    validate_parquet_stream(tmp_path / "good.parquet", _steps(good), RATE, batch_rows=64)
    gapped.to_parquet(tmp_path / "gap.parquet")  # the gap at row 130 is inside the batch of rows 128..191
    with pytest.raises(SessionError, match=r"step 0: column t: gap .* \(in the batch starting at row 128\)"):
        validate_parquet_stream(tmp_path / "gap.parquet", _steps(gapped), RATE, batch_rows=64)
