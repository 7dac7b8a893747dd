"""Validation of a session's samples against its manifest (in memory, or a Parquet file batch by batch).

Columns, finiteness, time order, the time base against ``sample_rate_hz`` (s, Hz), gaps (allowed
between steps), step labels and spans, and the physical plausibility of the declared SI units
(m/s², rad/s, µT). Every failure is a :class:`SessionError` naming the file, column, row or step.
Re-exported by :mod:`workbench.session`.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from workbench.errors import SessionError
from workbench.session_types import OPTIONAL_COLUMNS, REQUIRED_COLUMNS, StepRecord
from workbench.values import ACCEL, GYRO, MAG

GAP_FACTOR = 2.5  # an interval longer than 2.5 nominal sample intervals is a gap
RATE_TOLERANCE = 0.01  # sample_rate_hz may differ from the time column's rate by 1 %


def _check_time_base(t: np.ndarray, labels: np.ndarray, sample_rate_hz: float, source: str,
                     gaps_in_steps: bool) -> None:
    """Check the time column (s) against ``sample_rate_hz`` and allow gaps only between steps.

    A gap (an interval over :data:`GAP_FACTOR` nominal intervals) is normal where the recorder
    paused between steps: the samples either side carry different step labels, or one of them
    is unlabelled (``step = -1``). A gap inside a step is an error naming the step unless
    ``gaps_in_steps`` (a gap-aware analysis). The rate is the median interval of consecutive
    samples inside steps (or of all samples when nothing is labelled); more than
    :data:`RATE_TOLERANCE` off ``sample_rate_hz`` is an error naming both.
    """
    dt = np.diff(t)
    if not len(dt):
        return
    nominal = 1.0 / sample_rate_hz
    same = (labels[1:] == labels[:-1]) & (labels[1:] >= 0)
    inside = dt[same] if same.any() else dt
    measured = 1.0 / float(np.median(inside))
    if abs(measured - sample_rate_hz) > RATE_TOLERANCE * sample_rate_hz:
        raise SessionError(f"{source}: sample_rate_hz {sample_rate_hz:g} Hz disagrees with column t, whose median "
                           f"interval gives {measured:.4g} Hz (more than {RATE_TOLERANCE:.0%} off)")
    gap = (dt > GAP_FACTOR * nominal) & same
    if gap.any() and not gaps_in_steps:
        row = int(np.argmax(gap)) + 1
        raise SessionError(f"{source}: step {int(labels[row])}: column t: gap of {dt[row - 1]:.4g} s before row "
                           f"{row} (t={t[row]}) inside the step, sample interval {nominal:.4g} s "
                           "(gaps are allowed only between steps)")


def validate_samples(df: pd.DataFrame, steps: Sequence[StepRecord], sample_rate_hz: float, source: str,
                     require_complete: bool = True, check_labels: bool = True,
                     gaps_in_steps: bool = False) -> pd.DataFrame:
    """Check columns, finiteness, time order, time base and step labels; raise SessionError naming the problem.

    Gaps in time are allowed between steps (see :func:`_check_time_base`); ``gaps_in_steps``
    also allows them inside steps (for gap-aware analyses).
    """
    missing = [c for c in REQUIRED_COLUMNS if c not in df.columns]
    if missing:
        raise SessionError(f"{source}: missing column(s) {', '.join(missing)}")
    if len(df) == 0:
        raise SessionError(f"{source}: no samples")
    for col in [c for c in REQUIRED_COLUMNS + OPTIONAL_COLUMNS if c in df.columns]:
        try:
            kind = df[col].dtype  # numbers only: text digits, True / False, categories are no measurement
            if not pd.api.types.is_numeric_dtype(kind) or pd.api.types.is_bool_dtype(kind):
                raise TypeError
            values = df[col].to_numpy(float)
        except (TypeError, ValueError):
            raise SessionError(f"{source}: column {col}: not numeric ({df[col].dtype} values)") from None
        bad = ~np.isfinite(values)
        if bad.any():
            row = int(np.argmax(bad))
            raise SessionError(f"{source}: column {col}: NaN or infinite value at row {row} (t={df['t'].iloc[row]})")
    t = df["t"].to_numpy(float)
    dt = np.diff(t)
    if np.any(dt <= 0):
        row = int(np.argmax(dt <= 0)) + 1
        raise SessionError(f"{source}: column t: duplicate or non-increasing time at row {row} (t={t[row]})")
    labels = df["step"].to_numpy(float)
    if np.any(labels != np.round(labels)):
        row = int(np.argmax(labels != np.round(labels)))
        raise SessionError(f"{source}: column step: {labels[row]:g} at row {row} is not a whole step index")
    labels = labels.astype(np.int64)
    _check_time_base(t, labels, sample_rate_hz, source, gaps_in_steps)
    nominal = 1.0 / sample_rate_hz
    _check_units(df, source)
    if not check_labels:
        return df
    rows = _label_rows(labels)
    known = {s.index for s in steps}
    unknown = set(rows) - known - {-1}
    if unknown:
        raise SessionError(f"{source}: column step: label(s) {sorted(unknown)[:5]} match no step in session.json")
    for s in steps:
        if s.t_start < t[0] - 1.5 * nominal or s.t_end > t[-1] + 1.5 * nominal:
            raise SessionError(f"{source}: step {s.index} ({s.t_start:.3f}..{s.t_end:.3f} s) points outside "
                               f"the samples ({t[0]:.3f}..{t[-1]:.3f} s)")
        if require_complete and s.index not in rows:
            raise SessionError(f"{source}: step {s.index} ({s.kind}) has no samples")
        if s.index in rows:
            first, last = rows[s.index]  # t increases: the step's first and last sample times
            _check_step_span(source, s, float(t[first]), float(t[last]), nominal, gaps_in_steps)
    return df


def _label_rows(labels: np.ndarray) -> dict[int, tuple[int, int]]:
    """{label: (first row, last row)} of every label in ``labels`` (N,), from its runs of equal labels."""
    if not len(labels):
        return {}
    change = np.flatnonzero(labels[1:] != labels[:-1]) + 1
    starts, stops = np.r_[0, change], np.r_[change, len(labels)] - 1
    run_labels = labels[starts]
    names, first_run = np.unique(run_labels, return_index=True)
    _, last_from_end = np.unique(run_labels[::-1], return_index=True)
    last_run = len(run_labels) - 1 - last_from_end
    return {int(k): (int(a), int(b)) for k, a, b in zip(names, starts[first_run], stops[last_run])}


def _check_step_span(source: str, s: StepRecord, first: float, last: float, nominal: float,
                     gaps_in_steps: bool) -> None:
    """A step's samples (first..last, s) lie within its t_start..t_end and, unless gaps are allowed, fill it."""
    if first < s.t_start - 1.5 * nominal or last > s.t_end + 1.5 * nominal:
        raise SessionError(f"{source}: step {s.index}: samples at t={first:.3f}..{last:.3f} "
                           f"fall outside the step's t_start..t_end {s.t_start:.3f}..{s.t_end:.3f}")
    if gaps_in_steps:
        return
    for lo, hi in ((s.t_start, first), (last, s.t_end)):
        if hi - lo > GAP_FACTOR * nominal:
            raise SessionError(f"{source}: step {s.index}: column t: gap of {hi - lo:.4g} s at t={lo:.3f}..{hi:.3f} "
                               f"inside the step's t_start..t_end {s.t_start:.3f}..{s.t_end:.3f} (no samples there)")


def validate_parquet_stream(path: Path, steps: Sequence[StepRecord], sample_rate_hz: float,
                            require_complete: bool = True, batch_rows: int = 1 << 20,
                            gaps_in_steps: bool = False) -> None:
    """:func:`validate_samples` batch by batch over a Parquet file, in bounded memory.

    Each batch (with the last sample of the previous one, for time order and gaps) goes
    through the same checks; step coverage is accumulated across batches.
    """
    import pyarrow.parquet as pq

    pf = pq.ParquetFile(path, pre_buffer=False)  # pre-buffering caches every row group: memory grows with the file
    names = set(pf.schema_arrow.names)
    missing = [c for c in REQUIRED_COLUMNS if c not in names]
    if missing:
        raise SessionError(f"{path}: missing column(s) {', '.join(missing)}")
    cols = [c for c in REQUIRED_COLUMNS + OPTIONAL_COLUMNS if c in names]
    seen: dict[int, list[float]] = {}
    prev: pd.DataFrame | None = None
    offset = 0
    for batch in pf.iter_batches(batch_size=batch_rows, columns=cols):
        df = batch.to_pandas()
        chunk = df if prev is None else pd.concat([prev, df], ignore_index=True)
        try:
            validate_samples(chunk, [], sample_rate_hz, str(path), require_complete=False, check_labels=False,
                             gaps_in_steps=gaps_in_steps)
        except SessionError as exc:
            raise SessionError(f"{exc} (in the batch starting at row {offset})") from None
        lab, t = df["step"].to_numpy(), df["t"].to_numpy(float)
        for idx in np.unique(lab[lab >= 0]):
            ts = t[lab == idx]
            lo_hi = seen.setdefault(int(idx), [ts[0], ts[-1]])
            lo_hi[0], lo_hi[1] = min(lo_hi[0], ts[0]), max(lo_hi[1], ts[-1])
        prev, offset = df.iloc[-1:], offset + len(df)
    known = {s.index for s in steps}
    unknown = set(seen) - known
    if unknown:
        raise SessionError(f"{path}: column step: label(s) {sorted(unknown)[:5]} match no step in session.json")
    nominal = 1.0 / sample_rate_hz
    for s in steps:
        if s.index not in seen:
            if require_complete:
                raise SessionError(f"{path}: step {s.index} ({s.kind}) has no samples")
            continue
        lo, hi = seen[s.index]
        _check_step_span(str(path), s, lo, hi, nominal, gaps_in_steps)


def _check_units(df: pd.DataFrame, source: str) -> None:
    """Flag physically implausible magnitudes (wrong declared units)."""
    norm = np.median(_norm(df, ACCEL))
    if norm < 3.0 or norm > 30.0:
        raise SessionError(f"{source}: columns ax, ay, az: median |a| = {norm:.3g}, not m/s^2 "
                           "(given in g or mg? convert with an import profile)")
    gmax = max(np.abs(df[c].to_numpy(float)).max() for c in GYRO)
    if gmax > 60.0:
        raise SessionError(f"{source}: columns gx, gy, gz: |rate| up to {gmax:.3g}, not rad/s (deg/s?)")
    if all(c in df.columns for c in MAG):
        mn = np.median(_norm(df, MAG))
        if mn < 1.0 or mn > 1000.0:
            raise SessionError(f"{source}: columns mx, my, mz: median |m| = {mn:.3g}, not µT (gauss or nT?)")


def _norm(df: pd.DataFrame, cols: list[str]) -> np.ndarray:
    """(N,) Euclidean norm of the three columns ``cols`` of ``df``, row by row, from the columns as they are."""
    x, y, z = (df[c].to_numpy(float) for c in cols)
    return np.sqrt(x * x + y * y + z * z)
