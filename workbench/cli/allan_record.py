"""Reading the record of ``workbench allan``: a session folder, or a CSV / Parquet / text file of rate columns.

Rate samples (N, C) in SI (rad/s, m/s^2) with the sample rate (Hz): from a session's longest
static hold, or from a file's time column ``t``/``time`` (s; gaps become NaN rows) or ``--rate``.
A Parquet file is read column by column with pyarrow (no DataFrame). numpy, pandas and pyarrow
load when a record is read, not when the command line starts.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from workbench.errors import AnalysisError, SessionError

if TYPE_CHECKING:
    import numpy as np
    import pandas as pd

TIME_COLUMNS = ("t", "time")
TEXT_SUFFIXES = (".txt", ".dat")
RATE_TOLERANCE = 0.01  # relative spread of sample intervals accepted as a constant rate
RATE_RANGE_HZ = (1e-6, 1e7)  # a --rate outside this is a typo (the import profiles' range: a sample a
# fortnight to 10 MHz); its taus would overflow or underflow
MAX_ABS = 1e100  # |sample| beyond this is no measured rate or phase in SI: its squared differences
# (up to (N |x| / rate)^2 summed over N) would overflow float64 and read as a constant record
PIECE_ROWS = 1 << 20  # rows decoded at a time from a Parquet file (row groups up to this size are read whole)


def quantity_of(columns: list[str]) -> str | None:
    """``"gyro"`` for gx/gy/gz, ``"accel"`` for ax/ay/az, else None (generic SI data)."""
    from workbench.values import ACCEL, GYRO

    if set(columns) <= set(GYRO):
        return "gyro"
    if set(columns) <= set(ACCEL):
        return "accel"
    return None


def rate_from_time(t: np.ndarray, source: str) -> tuple[float, np.ndarray]:
    """Sample rate (Hz) from a time column (s) and the rows after which a gap (> 1.5 dt) opens.

    Raises when the intervals (gaps aside) vary by more than :data:`RATE_TOLERANCE`.
    """
    import numpy as np

    from workbench.analysis.allan import column_median

    dt = np.diff(np.asarray(t, float))
    if len(dt) == 0:
        raise AnalysisError(f"{source}: {len(t)} sample(s): too few to find the sample rate from the time column")
    if np.any(~np.isfinite(dt)) or np.any(dt <= 0):
        row = int(np.argmax(~(dt > 0))) + 1
        raise AnalysisError(f"{source}: time column is not strictly increasing (row {row})")
    nominal = float(column_median(dt[:, None])[0])
    gaps = np.flatnonzero(dt > 1.5 * nominal)
    regular = np.delete(dt, gaps)
    spread = float(np.max(np.abs(regular - nominal)) / nominal)
    if spread > RATE_TOLERANCE:
        row = int(np.argmax(np.abs(dt - nominal) * (dt <= 1.5 * nominal))) + 1
        raise AnalysisError(f"{source}: non-constant sample rate: interval {dt[row - 1]:.6g} s at row {row} vs "
                            f"nominal {nominal:.6g} s (resample first, or give --rate for an index-based record)")
    return 1.0 / nominal, gaps


def load_record(path: Path, columns: list[str] | None, rate: float | None) -> tuple[np.ndarray, float, list[str], str]:
    """Rate samples (N, C) SI, rate (Hz), column names and a source label from a session or file.

    Gaps in a time column become NaN rows, so the gap policy decides what happens to them.
    A ``rate`` outside :data:`RATE_RANGE_HZ`, no rate column, or a finite sample beyond
    :data:`MAX_ABS` is an AnalysisError naming the option, the file or the column and row.
    """
    y, fs, cols, label = _read_record(path, columns, None if rate is None else check_rate(rate))
    if not cols:
        raise AnalysisError(f"{path}: no rate column besides {', '.join(TIME_COLUMNS)} and step "
                            "(choose the rate columns with --columns)")
    _check_values(y, cols, label)
    return y, fs, cols, label


def check_rate(rate: float) -> float:
    """``rate`` (Hz) if finite and within :data:`RATE_RANGE_HZ`, else an AnalysisError naming ``--rate``."""
    lo, hi = RATE_RANGE_HZ
    if not lo <= rate <= hi:  # NaN fails too
        raise AnalysisError(f"--rate {rate!r}: expected a sample rate in {lo:g}..{hi:g} Hz")
    return float(rate)


def _check_values(y: np.ndarray, cols: list[str], source: str) -> None:
    """AnalysisError naming the column and row of the first finite sample beyond :data:`MAX_ABS`
    (NaN and infinities are gaps, for the gap policy; two NaN-ignoring reductions, no copy)."""
    import numpy as np

    if y.size == 0 or (np.fmax.reduce(y, axis=None) <= MAX_ABS and np.fmin.reduce(y, axis=None) >= -MAX_ABS):
        return
    with np.errstate(invalid="ignore"):
        bad = np.isfinite(y) & (np.abs(y) > MAX_ABS)
    if bad.any():
        row, j = np.unravel_index(int(np.argmax(bad)), bad.shape)
        raise AnalysisError(f"{source}: column {cols[j]}: value {y[row, j]:.4g} at row {row + 1} is beyond "
                            f"±{MAX_ABS:.0e}: not a measured rate or phase in SI")


def _read_record(path: Path, columns: list[str] | None,
                 rate: float | None) -> tuple[np.ndarray, float, list[str], str]:
    """:func:`load_record` before its checks of the columns and values."""
    import numpy as np

    if path.is_dir():
        from workbench.session import load_session
        from workbench.values import GYRO

        session = load_session(path)
        static = session.steps_of_kind("static")
        if not static:
            raise SessionError(f"{path}: no static step to analyse")
        step = max(static, key=lambda s: s.duration)
        cols = columns or GYRO
        df = session.step_samples(step.index)
        return _columns(df, cols, path), float(rate or session.sample_rate_hz), cols, f"{path}: step {step.index}"
    if not path.exists():
        raise AnalysisError(f"{path}: no such file or session folder")
    if path.suffix.lower() in TEXT_SUFFIXES:
        if rate is None:
            raise AnalysisError(f"{path}: a text file of numbers has no time column: give the sample rate with --rate HZ")
        return _text_column(path), float(rate), columns or ["data"], str(path)
    table = _parquet_columns(path, columns, rate is None) if path.suffix.lower() == ".parquet" else None
    if table is None:
        from workbench.session import read_samples

        df = read_samples(path)
        time_col = next((c for c in TIME_COLUMNS if c in df.columns), None)
        cols = columns or [c for c in df.columns if c not in (*TIME_COLUMNS, "step")]
        y = _columns(df, cols, path)
        t = df[time_col].to_numpy(float) if time_col is not None else None
    else:
        y, t, cols = table
    if rate is None:
        if t is None:
            raise AnalysisError(f"{path}: no time column (t or time): give the sample rate with --rate HZ")
        rate, gaps = rate_from_time(t, str(path))
        if len(gaps):
            y = np.insert(y, gaps + 1, np.nan, axis=0)
    return y, float(rate), cols, str(path)


def _parquet_columns(path: Path, columns: list[str] | None,
                     want_time: bool) -> tuple[np.ndarray, np.ndarray | None, list[str]] | None:
    """Rate columns (N, C) float64, the time column (or None) and the column names of a Parquet
    file, read piece by piece with pyarrow (no DataFrame, no copy beyond the (N, C) array). The
    samples are the view ``buf[:, 1:].T`` of a :func:`workbench.analysis.allan.rate_buffer`
    (``buf`` (C, N + 1)), so the phase can take their place (:func:`workbench.analysis.allan.phase`).

    None when a chosen column is not numeric: the DataFrame path then names the offending cell.
    """
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    from workbench.analysis.allan import rate_buffer

    try:
        pf = pq.ParquetFile(path)
        schema = pf.schema_arrow
    except Exception as exc:  # pyarrow raises many types for unreadable files
        raise AnalysisError(f"{path}: cannot read samples ({type(exc).__name__}: {str(exc)[:120]})") from None
    names = list(schema.names)
    time_col = next((c for c in TIME_COLUMNS if c in names), None)
    cols = columns or [c for c in names if c not in (*TIME_COLUMNS, "step")]
    missing = [c for c in cols if c not in names]
    if missing:
        raise AnalysisError(f"{path}: no column(s) {', '.join(missing)} (has {', '.join(names)})")

    def numeric(c: str) -> bool:
        kind = schema.field(c).type
        return pa.types.is_floating(kind) or pa.types.is_integer(kind)

    if not all(numeric(c) for c in cols):
        return None
    n = pf.metadata.num_rows
    buf = rate_buffer(n, len(cols))  # channel-major, column 0 spare: the phase can be integrated in place
    t = np.empty(n) if want_time and time_col is not None else None
    wanted = cols + ([time_col] if t is not None else [])
    try:
        start = 0
        for rows, pieces in _pieces(pf, wanted):
            for j, piece in enumerate(pieces):
                _fill(piece, buf[j, 1 + start:] if j < len(cols) else t[start:])
            start += rows
    except Exception as exc:
        raise AnalysisError(f"{path}: cannot read samples ({type(exc).__name__}: {str(exc)[:120]})") from None
    finally:
        pa.default_memory_pool().release_unused()  # the decode buffers pyarrow keeps for reuse
    return buf[:, 1:].T, t, cols


def _pieces(pf, columns: list[str]):
    """The file's rows in order: (row count, iterator over the pyarrow arrays of ``columns``). One
    column of one row group at a time when the groups are small (:data:`PIECE_ROWS`), else batches
    of that many rows. Decoding a piece into the memory pyarrow just released is several times
    faster than decoding whole columns into fresh memory, and keeps its pool to a few pieces."""
    meta = pf.metadata
    if all(meta.row_group(i).num_rows <= PIECE_ROWS for i in range(meta.num_row_groups)):
        for i in range(meta.num_row_groups):
            yield meta.row_group(i).num_rows, (pf.read_row_group(i, columns=[c], use_threads=False).column(0)
                                               for c in columns)
    else:
        for batch in pf.iter_batches(batch_size=PIECE_ROWS, columns=columns, use_threads=False):
            yield batch.num_rows, iter(batch.columns)


def _fill(column, out: np.ndarray) -> None:
    """Copy a numeric pyarrow Array or ChunkedArray into the start of ``out`` float64, nulls as NaN.

    From the chunks' data buffers: pyarrow's own ``to_numpy`` imports pandas (~0.5 s).
    """
    import numpy as np
    import pyarrow as pa

    start = 0
    for chunk in column.chunks if isinstance(column, pa.ChunkedArray) else [column]:
        if chunk.null_count or chunk.type != pa.float64():
            import pyarrow.compute as pc  # ~0.2 s: only for integer columns or nulls

            chunk = pc.fill_null(chunk.cast(pa.float64()), float("nan"))
        values = np.frombuffer(chunk.buffers()[1], dtype=np.float64)[chunk.offset:chunk.offset + len(chunk)]
        out[start:start + len(chunk)] = values
        start += len(chunk)


def _text_column(path: Path) -> np.ndarray:
    """One number per line (Stable32's data files; ``#`` comments and blank lines skipped), (N, 1)."""
    import numpy as np

    values = []
    for row, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        try:
            values.append(float(text.split()[0]))
        except ValueError:
            raise AnalysisError(f"{path}: line {row}: {text[:40]!r} is not a number") from None
    return np.asarray(values, float)[:, None]


def _columns(df: pd.DataFrame, cols: list[str], path: Path) -> np.ndarray:
    import numpy as np
    import pandas as pd

    missing = [c for c in cols if c not in df.columns]
    if missing:
        raise AnalysisError(f"{path}: no column(s) {', '.join(missing)} (has {', '.join(map(str, df.columns))})")
    if df.empty:  # a header alone: pandas types its columns as text
        return np.empty((0, len(cols)))
    for c in cols:  # a column with a non-numeric cell is refused, never dropped or turned into NaN
        if not pd.api.types.is_numeric_dtype(df[c]) or pd.api.types.is_bool_dtype(df[c]):
            bad = np.flatnonzero((pd.to_numeric(df[c], errors="coerce").isna() & df[c].notna()).to_numpy())
            row = int(bad[0]) if len(bad) else 0
            raise AnalysisError(f"{path}: column {c}: non-numeric cell {df[c].iloc[row]!r} at row {row + 1} "
                                f"(choose the rate columns with --columns)")
    return df[cols].to_numpy(float)
