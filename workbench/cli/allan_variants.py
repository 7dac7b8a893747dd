"""``workbench allan --stat NAME`` (one statistic of the stability family) and ``--method gmwm`` (the GMWM fit).

Both read the record with :func:`workbench.cli.allan_record.load_record`, print a table (SI of
the input; GMWM's IEEE 952 equivalents in lab units) and write ``--out`` with
:mod:`workbench.cli.allan_csv`.
"""

from __future__ import annotations

from pathlib import Path

from rich.table import Table

from workbench.cli import out, styled
from workbench.cli.allan_csv import FAMILY_COLUMNS, GMWM_COLUMNS, family_rows, write_csv
from workbench.cli.allan_record import load_record, quantity_of
from workbench.errors import AnalysisError

RICH_ROWS = 200  # rows of a printed table above which it is laid out as plain text


def parse_taus(taus: str) -> str | list[float]:
    """``octave`` | ``decade`` | ``all`` | ``<k>-per-decade`` as given, or ``T1,T2,...`` as taus in s."""
    if "," not in taus and not taus.replace(".", "", 1).replace("e", "", 1).replace("-", "").isdigit():
        return taus
    try:
        return [float(t) for t in taus.split(",") if t.strip()]
    except ValueError:
        raise AnalysisError(f"--taus {taus!r}: expected octave, decade, all or taus in s (T1,T2,...)") from None


def run_family(source: Path, cols: list[str] | None, rate: float | None, stat: str, data_type: str, taus: str,
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
    header = ("column", "tau s", stat, f"{level:.3g} interval", "n", "alpha", "edf")
    rows = [(col, f"{c.curve.tau[k]:.4g}", f"{c.curve.dev[k]:.5g}",
             "" if not c.edf[k] == c.edf[k] else f"{c.lo[k]:.5g} .. {c.hi[k]:.5g}",
             str(int(c.curve.n[k])), "" if c.alpha[k] != c.alpha[k] else str(int(c.alpha[k])),
             "" if c.edf[k] != c.edf[k] else f"{c.edf[k]:.4g}")
            for col, c in results for k in range(len(c.curve.tau))]
    print_rows(f"{stat} of {label} ({data_type} data, SI of the input)", header, rows)
    if out_csv is not None:
        write_csv(out_csv, FAMILY_COLUMNS, family_rows(results))
        out.print(f"curves: {out_csv}")


def print_rows(title: str, header: tuple[str, ...], rows: list[tuple[str, ...]]) -> None:
    """A table of text cells: a Rich table up to :data:`RICH_ROWS` rows, aligned plain columns beyond
    (Rich lays a table out at ~10 ms per row: 30 s for the 3 x 2500 taus of ``--taus all`` on 1e4 samples)."""
    if len(rows) <= RICH_ROWS:
        t = Table(*header, title=title)
        for row in rows:
            t.add_row(*row)
        out.print(t)
        return
    widths = [max(len(h), *(len(r[j]) for r in rows)) for j, h in enumerate(header)]
    lines = [title, "  ".join(h.ljust(w) for h, w in zip(header, widths)).rstrip()]
    lines += ["  ".join(cell.ljust(w) for cell, w in zip(r, widths)).rstrip() for r in rows]
    out.file.write("\n".join(lines) + "\n")


def run_gmwm(source: Path, cols: list[str] | None, rate: float | None, processes: str, bootstrap: int,
          gap_policy: str, out_csv: Path | None) -> None:
    """``--method gmwm``: the GMWM fit of every column, its parameters and IEEE 952 equivalents."""
    from workbench.analysis.allan import prepare_rate_data
    from workbench.analysis.gmwm import MIN_BOOTSTRAP, fit_gmwm, parse_model, term_interval_text

    parse_model(processes)  # a bad model text fails before the record is read
    if bootstrap < MIN_BOOTSTRAP:
        raise AnalysisError(f"--bootstrap {bootstrap}: must be {MIN_BOOTSTRAP} or more")
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
            t.add_row(f.column, name, term_interval_text(quantity, name, v, lo, hi, f.resolved[name]))
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
