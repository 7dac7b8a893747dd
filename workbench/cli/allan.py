"""``workbench allan``: Allan deviation, intervals and noise terms of any rate recording.

Input: a session folder (its longest static hold, rate from the manifest), or a CSV / Parquet
file of rate columns in SI (rad/s, m/s^2) with a time column ``t``/``time`` (s) or none when
``--rate`` is given. Output: a table of the IEEE 952 terms in lab units, ``--out curves.csv``
(one row per column and tau: deviation, 95 % interval, EDF, noise exponent) and ``--plot``.

This module holds the command (its arguments, the choice of path, streaming); the record is read
by :mod:`workbench.cli.allan_record`, the terms table is :mod:`workbench.cli.allan_tables`, the
CSV files :mod:`workbench.cli.allan_csv`, ``--stat`` and ``--method gmwm`` :mod:`workbench.cli.allan_variants`
(their names are re-exported here).

A Parquet file is read column by column with pyarrow (no DataFrame); one of
:data:`STREAM_SAMPLES` values or more (or over a quarter of the RAM) is streamed in bounded
memory (:mod:`workbench.analysis.allan_stream`). Only what the command needs is imported:
no pandas, scipy or numba for a record that fits the numpy kernels.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import typer

from workbench.cli import out, styled
from workbench.cli.allan_csv import (CURVE_COLUMNS, FAMILY_COLUMNS, GMWM_COLUMNS, curve_rows,  # noqa: F401
                                     family_rows, write_csv)
from workbench.cli.allan_record import (RATE_TOLERANCE, TEXT_SUFFIXES, TIME_COLUMNS, check_rate,  # noqa: F401
                                        load_record, quantity_of, rate_from_time)
from workbench.cli.allan_tables import TERM_NAMES, TERM_ROWS, print_terms, terms_tables  # noqa: F401
from workbench.cli.allan_variants import parse_taus, run_family, run_gmwm  # noqa: F401
from workbench.errors import AnalysisError

if TYPE_CHECKING:  # the fit (scipy.stats, cvxpy) loads when the command runs
    from workbench.analysis.allan_fit import AllanAnalysis

STREAM_SAMPLES = 3e8  # values (rows x rate columns) from which a Parquet file is streamed: one channel of
# 1e8 samples took 3.4 s CPU in memory vs 6.0 s streamed, 3e8 14.1 s / 2.5 GB vs 15.9 s / 0.42 GB


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
        processes: str = typer.Option("wn+fl+rw", "--processes", help="With --method gmwm: the model, terms wn qn "
                                                                      "fl rw dr gm joined by + (k*gm repeats)."),
        bootstrap: int = typer.Option(100, "--bootstrap", help="With --method gmwm: simulated records for the "
                                                               "weighting matrix and the intervals (>= 50)."),
    ) -> None:
        """Overlapping Allan deviation with 95 % intervals and the IEEE 952 noise terms (or --stat NAME)."""
        cols = [c.strip() for c in columns.split(",")] if columns else None
        if stat is not None:
            run_family(source, cols, rate, stat, data_type, taus, confidence, out_csv)
            return
        if method not in ("ieee952", "gmwm"):
            raise AnalysisError(f"--method {method!r} is not ieee952 or gmwm")
        if method == "gmwm":
            run_gmwm(source, cols, rate, processes, bootstrap, gap_policy, out_csv)
            return
        if stream or _too_large(source, cols):
            an = _streamed(source, cols, rate, taus)
        else:
            from workbench.analysis.allan_fit import analyze_record

            y, fs, cols, label = load_record(source, cols, rate)
            an = analyze_record(y, fs, cols, quantity_of(cols), taus, gap_policy, label, overwrite=True)
        for w in an.warnings:
            out.print(styled("warning:", "yellow", f" {w}"))
        print_terms(an)
        if out_csv is not None:
            write_csv(out_csv, CURVE_COLUMNS, curve_rows(an))
            out.print(f"curves: {out_csv}")
        if plot is not None:
            import matplotlib.pyplot as plt

            from workbench.plots.allan import plot_triads

            fig = plot_triads({an.quantity or "data": an})
            try:
                plot.parent.mkdir(parents=True, exist_ok=True)
                fig.savefig(plot, dpi=110, bbox_inches="tight")
            except OSError as exc:
                raise AnalysisError(f"--plot {plot}: cannot write ({exc.strerror or exc})") from None
            finally:
                plt.close(fig)
            out.print(f"figure: {plot}")


def _too_large(source: Path, cols: list[str] | None) -> bool:
    """A Parquet file whose rate columns hold at least :data:`STREAM_SAMPLES` values, or more than a
    quarter of the physical memory as float64: streamed (as fast from ~3e8 values, bounded memory)."""
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
    rate = check_rate(rate)
    if cols is None:
        import pyarrow.parquet as pq

        cols = [c for c in pq.ParquetFile(source).schema_arrow.names if c not in (*TIME_COLUMNS, "step")]
    return analyze_stream(parquet_batches(source, cols), rate, cols, quantity_of(cols), taus, str(source))
