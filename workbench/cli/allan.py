"""``workbench allan``: Allan deviation, intervals and noise terms of any rate recording.

Input: a session folder (its longest static hold, rate from the manifest), or a CSV / Parquet
file of rate columns in SI (rad/s, m/s^2) with a time column ``t``/``time`` (s) or none when
``--rate`` is given. Output: a table of the IEEE 952 terms in lab units, ``--out curves.csv``
(one row per column and tau: deviation, 95 % interval, EDF, noise exponent) and ``--plot``.

A Parquet file is read column by column with pyarrow (no DataFrame); one of
:data:`STREAM_SAMPLES` values or more (or over a quarter of the RAM) is streamed in bounded
memory (:mod:`workbench.analysis.allan_stream`). Only what the command needs is imported:
no pandas, scipy or numba for a record that fits the numpy kernels.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import typer
from rich.table import Table

from workbench.cli import out, styled
from workbench.errors import AnalysisError, SessionError

if TYPE_CHECKING:  # numpy, pandas, sessions and the fit (scipy.stats, cvxpy) load when the command runs
    import numpy as np
    import pandas as pd

    from workbench.analysis.allan_fit import AllanAnalysis

TIME_COLUMNS = ("t", "time")
TEXT_SUFFIXES = (".txt", ".dat")
STREAM_SAMPLES = 1e8  # values (rows x rate columns) from which a Parquet file is streamed
RATE_TOLERANCE = 0.01  # relative spread of sample intervals accepted as a constant rate


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

    dt = np.diff(np.asarray(t, float))
    if len(dt) == 0 or np.any(~np.isfinite(dt)) or np.any(dt <= 0):
        row = int(np.argmax(~(dt > 0))) + 1 if len(dt) else 0
        raise AnalysisError(f"{source}: time column is not strictly increasing (row {row})")
    nominal = float(np.median(dt))
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
    """
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
    file, read column by column with pyarrow (no DataFrame, no copy beyond the (N, C) array).

    None when a chosen column is not numeric: the DataFrame path then names the offending cell.
    """
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

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
    y = np.empty((len(cols), n))  # channel-major: each column copied contiguously; returned as the (N, C) view
    t = np.empty(n) if want_time and time_col is not None else None
    try:
        for j, c in enumerate(cols):
            _fill(pf.read(columns=[c], use_threads=False).column(0), y[j])
        if t is not None:
            _fill(pf.read(columns=[time_col], use_threads=False).column(0), t)
    except Exception as exc:
        raise AnalysisError(f"{path}: cannot read samples ({type(exc).__name__}: {str(exc)[:120]})") from None
    return y.T, t, cols


def _fill(column, out: np.ndarray) -> None:
    """Copy a numeric pyarrow ChunkedArray into ``out`` (n,) float64, nulls as NaN.

    From the chunks' data buffers: pyarrow's own ``to_numpy`` imports pandas (~0.5 s).
    """
    import numpy as np
    import pyarrow as pa

    start = 0
    for chunk in column.chunks:
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
    for c in cols:  # a column with a non-numeric cell is refused, never dropped or turned into NaN
        if not pd.api.types.is_numeric_dtype(df[c]) or pd.api.types.is_bool_dtype(df[c]):
            bad = np.flatnonzero((pd.to_numeric(df[c], errors="coerce").isna() & df[c].notna()).to_numpy())
            row = int(bad[0]) if len(bad) else 0
            raise AnalysisError(f"{path}: column {c}: non-numeric cell {df[c].iloc[row]!r} at row {row + 1} "
                                f"(choose the rate columns with --columns)")
    return df[cols].to_numpy(float)


CURVE_COLUMNS = ("column", "tau_s", "m", "n", "adev", "adev_lo95", "adev_hi95", "edf", "alpha")


def curve_rows(an: AllanAnalysis) -> list[tuple]:
    """One row per column and tau (:data:`CURVE_COLUMNS`): tau_s, adev and its 95 % interval
    (input SI unit), edf, alpha."""
    c = an.ci.curve
    return [(col, float(c.tau[k]), int(c.m[k]), int(c.n[k]), float(c.dev[k, j]), float(an.ci.lo[k, j]),
             float(an.ci.hi[k, j]), float(an.ci.edf[k, j]), int(an.ci.alpha[k, j]))
            for j, col in enumerate(c.columns) for k in range(len(c.tau))]


def write_csv(path: Path, header: tuple[str, ...] | list[str], rows: list[tuple]) -> None:
    """A CSV file of ``rows`` (floats as Python's shortest round-trip repr, as pandas writes them),
    written atomically."""
    import csv
    import io

    from workbench.files import atomic_write_text

    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, buf.getvalue())


TERM_NAMES = {"quantization": "Q quantization", "white": "N white noise", "bias_instability": "B bias instability",
              "rrw": "K rate random walk", "rate_ramp": "R rate ramp"}
# rows of the terms table: (row label, term, source); read-offs are the plain-ADEV values
TERM_ROWS = (("Q", "quantization", "fit"), ("N", "white", "fit"), ("B", "bias_instability", "fit"),
             ("K", "rrw", "fit"), ("R", "rate_ramp", "fit"), ("N 1 s", "white", "read_off"),
             ("B min", "bias_instability", "read_off"))


def _term_unit(quantity: str | None, term: str) -> str | None:
    from workbench.analysis.allan_terms import TERM_UNITS

    return TERM_UNITS.get(quantity or "", {}).get(term)


def _value(quantity: str | None, term: str, value_si: float) -> str:
    from workbench import units

    unit = _term_unit(quantity, term)
    return f"{value_si if unit is None else units.to_unit(value_si, unit):.3g}"


def _cell(an: AllanAnalysis, fit, term: str, source: str) -> str:
    if source == "read_off":
        return _value(an.quantity, term, fit.read_off[term])
    est = fit.terms[term]
    if not est.observed:
        return f"n/o < {_value(an.quantity, term, est.ci95[1])}"
    lo, hi = (_value(an.quantity, term, v) for v in est.ci95)
    return f"{_value(an.quantity, term, est.value)} [{lo}, {hi}]"


def terms_tables(an: AllanAnalysis, width: int) -> list[Table]:
    """The IEEE 952 terms as tables at most ``width`` characters wide: one row per term with its lab
    unit in a column of its own, one column per data column (as many per table as fit), the term
    names in the caption; values in the unit of the row, 95 % interval in brackets."""
    from rich import box

    from workbench import units

    unit_text = {term: "SI" if _term_unit(an.quantity, term) is None else units.label(_term_unit(an.quantity, term))
                 for _, term, _ in TERM_ROWS}
    cells = {f.column: [_cell(an, f, term, source) for _, term, source in TERM_ROWS] for f in an.fits}
    label_w = max(len(r[0]) for r in TERM_ROWS)
    cell_w = max([len(c) for col in cells.values() for c in col] + [len(c) for c in cells])
    fixed = label_w + max(len(u) for u in unit_text.values()) + 4  # two columns and their padding
    per_table = max(1, (width - fixed) // (cell_w + 2))
    what = {"gyro": "gyro", "accel": "accel"}.get(an.quantity, "SI input")
    caption = (", ".join(TERM_NAMES.values()) + "; read-offs: N at τ = 1 s, B = min ADEV / 0.664; [95 % interval]; "
               "n/o = not observed, < its 95 % upper bound")
    tables = []
    for start in range(0, len(an.fits), per_table):
        fits = an.fits[start:start + per_table]
        t = Table("term", "unit", *(f.column for f in fits), box=box.SIMPLE_HEAD, pad_edge=False,
                  title=f"IEEE 952 terms ({what})", title_justify="left",
                  caption=caption if start + per_table >= len(an.fits) else None, caption_justify="left")
        for k, (label, term, _) in enumerate(TERM_ROWS):
            t.add_row(label, unit_text[term], *(cells[f.column][k] for f in fits))
        tables.append(t)
    return tables


def _print_terms(an: AllanAnalysis) -> None:
    for t in terms_tables(an, out.width):
        out.print(t)


def register(app: typer.Typer) -> None:
    """Add the ``allan`` command."""

    @app.command("allan")
    def allan_cmd(
        source: Path = typer.Argument(..., help="Session folder, or CSV / Parquet file of rate columns (SI)."),
        columns: str = typer.Option(None, "--columns", help="Comma-separated rate columns (default: gx,gy,gz for a "
                                                            "session, every numeric column for a file)."),
        rate: float = typer.Option(None, "--rate", help="Sample rate, Hz (needed when the file has no time column)."),
        taus: str = typer.Option("octave", "--taus", help="octave | decade | <k>-per-decade"),
        out_csv: Path = typer.Option(None, "--out", help="Write the curves (one row per column and tau) to this CSV."),
        plot: Path = typer.Option(None, "--plot", help="Write the ADEV figure (PNG) here."),
        gap_policy: str = typer.Option("error", "--gap-policy", help="NaN / time gaps: error | longest | split"),
        stream: bool = typer.Option(False, "--stream", help="Stream the Parquet file (automatic from "
                                                            f"{STREAM_SAMPLES:.0e} samples or a quarter of the RAM; no gap policy; "
                                                            "noise exponents from the curve's slopes)."),
        stat: str = typer.Option(None, "--stat", help="One statistic of the family instead of the IEEE 952 fit: adev "
                                                      "oadev mdev tdev hdev ohdev totdev mtotdev ttotdev htotdev theo1 "
                                                      "theoh mtie tierms."),
        data_type: str = typer.Option("freq", "--data-type", help="With --stat: freq (rate samples) | phase (angle, "
                                                                   "time error)."),
        confidence: float = typer.Option(0.95, "--confidence", help="With --stat: two-sided interval level "
                                                                    "(0.683 = Stable32's 1 sigma)."),
        method: str = typer.Option("ieee952", "--method", help="Noise-model fit: ieee952 (Allan-variance terms) | "
                                                               "gmwm (wavelet-variance fit of --processes)."),
        processes: str = typer.Option("wn+2gm+rw", "--processes", help="With --method gmwm: the model, terms wn qn "
                                                                       "rw dr gm joined by + (k*gm repeats)."),
        bootstrap: int = typer.Option(50, "--bootstrap", help="With --method gmwm: simulated records for the "
                                                              "optimal weighting matrix (0 = diagonal weights)."),
    ) -> None:
        """Overlapping Allan deviation with 95 % intervals and the IEEE 952 noise terms (or --stat NAME)."""
        cols = [c.strip() for c in columns.split(",")] if columns else None
        if stat is not None:
            _family(source, cols, rate, stat, data_type, taus, confidence, out_csv)
            return
        if method not in ("ieee952", "gmwm"):
            raise AnalysisError(f"--method {method!r} is not ieee952 or gmwm")
        if method == "gmwm":
            _gmwm(source, cols, rate, processes, bootstrap, gap_policy, out_csv)
            return
        if stream or _too_large(source, cols):
            an = _streamed(source, cols, rate, taus)
        else:
            from workbench.analysis.allan_fit import analyze_record

            y, fs, cols, label = load_record(source, cols, rate)
            an = analyze_record(y, fs, cols, quantity_of(cols), taus, gap_policy, label)
        for w in an.warnings:
            out.print(styled("warning:", "yellow", f" {w}"))
        _print_terms(an)
        if out_csv is not None:
            write_csv(out_csv, CURVE_COLUMNS, curve_rows(an))
            out.print(f"curves: {out_csv}")
        if plot is not None:
            import matplotlib.pyplot as plt

            from workbench.plots.allan import plot_triads

            fig = plot_triads({an.quantity or "data": an})
            plot.parent.mkdir(parents=True, exist_ok=True)
            fig.savefig(plot, dpi=110, bbox_inches="tight")
            plt.close(fig)
            out.print(f"figure: {plot}")


def _too_large(source: Path, cols: list[str] | None) -> bool:
    """A Parquet file whose rate columns hold at least :data:`STREAM_SAMPLES` values, or more than a
    quarter of the physical memory as float64: streamed (faster from 1e8 samples, bounded memory)."""
    if source.suffix.lower() != ".parquet" or not source.is_file():
        return False
    import os

    import pyarrow.parquet as pq

    try:
        pf = pq.ParquetFile(source)
    except Exception:  # unreadable: the in-memory path names the problem
        return False
    n_cols = len(cols) if cols else sum(1 for c in pf.schema_arrow.names if c not in (*TIME_COLUMNS, "step"))
    values = pf.metadata.num_rows * n_cols
    try:
        ram = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        ram = 1 << 62
    return values >= STREAM_SAMPLES or 8 * values > ram / 4


def _streamed(source: Path, cols: list[str] | None, rate: float | None, taus: str) -> AllanAnalysis:
    """The full analysis (deviations, intervals with noise identification, term fit) streamed."""
    from workbench.analysis.allan_fit import analyze_stream
    from workbench.analysis.allan_stream import parquet_batches

    if source.suffix.lower() != ".parquet" or rate is None:
        raise AnalysisError(f"{source}: streaming (--stream, or a record of {STREAM_SAMPLES:.0e} samples or more) "
                            "needs a .parquet file and --rate")
    if cols is None:
        import pyarrow.parquet as pq

        cols = [c for c in pq.ParquetFile(source).schema_arrow.names if c not in (*TIME_COLUMNS, "step")]
    return analyze_stream(parquet_batches(source, cols), rate, cols, quantity_of(cols), taus, str(source))


def parse_taus(taus: str) -> str | list[float]:
    """``octave`` | ``decade`` | ``all`` | ``<k>-per-decade`` as given, or ``T1,T2,...`` as taus in s."""
    if "," not in taus and not taus.replace(".", "", 1).replace("e", "", 1).replace("-", "").isdigit():
        return taus
    try:
        return [float(t) for t in taus.split(",") if t.strip()]
    except ValueError:
        raise AnalysisError(f"--taus {taus!r}: expected octave, decade, all or taus in s (T1,T2,...)") from None


FAMILY_COLUMNS = ("column", "tau", "dev", "dev_lo", "dev_hi", "n", "alpha", "edf")


def family_rows(results: list) -> list[tuple]:
    """One row per column and tau (:data:`FAMILY_COLUMNS`, SI of the input; NaN written as empty)."""
    def num(v: float) -> float | str:
        return "" if v != v else float(v)

    return [(col, float(c.curve.tau[k]), float(c.curve.dev[k]), num(c.lo[k]), num(c.hi[k]), int(c.curve.n[k]),
             num(c.alpha[k]), num(c.edf[k]))
            for col, c in results for k in range(len(c.curve.tau))]


def _family(source: Path, cols: list[str] | None, rate: float | None, stat: str, data_type: str, taus: str,
            level: float, out_csv: Path | None) -> None:
    """``--stat``: one statistic of :mod:`workbench.analysis.stability` per column, with intervals."""
    from workbench.analysis.stability import STATS, stability, to_phase
    from workbench.analysis.stability_ci import intervals

    if stat not in STATS:
        raise AnalysisError(f"--stat {stat!r} is not one of {', '.join(STATS)}")
    if data_type not in ("freq", "phase"):
        raise AnalysisError(f"--data-type {data_type!r} is not freq or phase")
    if not 0.0 < level < 1.0:
        raise AnalysisError(f"--confidence {level!r} must lie between 0 and 1")
    y, fs, cols, label = load_record(source, cols, rate)
    grid = parse_taus(taus)
    results = []
    for j, col in enumerate(cols):
        try:
            curve = stability(y[:, j], fs, stat, data_type, grid)
        except AnalysisError as exc:
            raise AnalysisError(f"{label}: column {col}: {exc}") from None
        results.append((col, intervals(curve, to_phase(y[:, j], fs, data_type), level)))
    t = Table("column", "tau s", stat, f"{level:.3g} interval", "n", "alpha", "edf",
              title=f"{stat} of {label} ({data_type} data, SI of the input)")
    for col, c in results:
        for k in range(len(c.curve.tau)):
            t.add_row(col, f"{c.curve.tau[k]:.4g}", f"{c.curve.dev[k]:.5g}",
                      "" if not c.edf[k] == c.edf[k] else f"{c.lo[k]:.5g} .. {c.hi[k]:.5g}",
                      str(int(c.curve.n[k])), "" if c.alpha[k] != c.alpha[k] else str(int(c.alpha[k])),
                      "" if c.edf[k] != c.edf[k] else f"{c.edf[k]:.4g}")
    out.print(t)
    if out_csv is not None:
        write_csv(out_csv, FAMILY_COLUMNS, family_rows(results))
        out.print(f"curves: {out_csv}")


GMWM_COLUMNS = ("column", "parameter", "value", "lo95", "hi95")


def _gmwm(source: Path, cols: list[str] | None, rate: float | None, processes: str, bootstrap: int,
          gap_policy: str, out_csv: Path | None) -> None:
    """``--method gmwm``: the GMWM fit of every column, its parameters and IEEE 952 equivalents."""
    from workbench.analysis.allan import prepare_rate_data
    from workbench.analysis.allan_terms import term_text
    from workbench.analysis.gmwm import fit_gmwm, parse_model

    parse_model(processes)  # a bad model text fails before the record is read
    if bootstrap < 0:
        raise AnalysisError(f"--bootstrap {bootstrap}: must be 0 or more")
    y, fs, cols, label = load_record(source, cols, rate)
    quantity = quantity_of(cols)
    segments, warnings = prepare_rate_data(y, tuple(cols), label, gap_policy, quantity)
    for w in warnings:
        out.print(styled("warning:", "yellow", f" {w}"))
    seg = max(segments, key=len)
    fits = []
    for j, col in enumerate(cols):
        try:
            fits.append(fit_gmwm(seg[:, j], fs, processes, col, bootstrap=bootstrap))
        except AnalysisError as exc:
            raise AnalysisError(f"{label}: column {col}: {exc}") from None
    t = Table("column", "term", "value [95 % interval]",
              title=f"GMWM {processes} of {label} (IEEE 952 equivalents in lab units; Gauss-Markov SI)")
    rows = []
    for f in fits:
        for name, (v, lo, hi) in f.terms.items():
            t.add_row(f.column, name, f"{term_text(quantity, name, v)} [{term_text(quantity, name, lo).split(' ', 1)[1]}"
                                      f" .. {term_text(quantity, name, hi).split(' ', 1)[1]}]")
        for name, v, (lo, hi) in zip(f.names(), f.theta, f.ci95):
            rows.append((f.column, name, float(v), float(lo), float(hi)))
            if name.startswith("gm"):
                unit = "s" if name.endswith("tau_c") else {"gyro": "rad/s", "accel": "m/s^2"}.get(quantity, "SI")
                t.add_row(f.column, name, f"{v:.4g} {unit} [{lo:.4g} .. {hi:.4g}]")
        rows += [(f.column, f"ieee_{k}", v, lo, hi) for k, (v, lo, hi) in f.terms.items()]
    out.print(t)
    if out_csv is not None:
        write_csv(out_csv, GMWM_COLUMNS, rows)
        out.print(f"parameters: {out_csv}")
