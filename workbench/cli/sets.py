"""``workbench sets``: list, show, diff, export, approve and merge calibration sets."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import typer
from rich import box
from rich.table import Table

from workbench.calset import CalibrationSet, atomic_write_text, merge
from workbench.cli import out
from workbench.diff import diff_sets
from workbench.registry import exporter, exporters
from workbench.store import Store
from workbench.units import DISPLAY, fmt, to_unit

sets_app = typer.Typer(no_args_is_help=True, help="Calibration sets: list, show, diff, export, approve, merge.")


def load_set_ref(ref: str) -> CalibrationSet:
    """A set from a calibration JSON file path or a stored set's id (or unique id prefix)."""
    p = Path(ref)
    if p.suffix == ".json" or p.exists():
        return CalibrationSet.load(p)
    return Store().get_set(ref)


@sets_app.command("list")
def list_sets(unit: str = typer.Option(None, "--unit", help="Only this unit serial."),
              format: str = typer.Option("table", "--format", help="table | json")) -> None:
    """List stored calibration sets, newest first."""
    infos = Store().list_sets(unit)
    if format == "json":
        out.print_json(json.dumps([{"id": i.id, "serial": i.serial, "model": i.model, "version": i.version,
                                    "created": i.created, "procedures": list(i.procedures),
                                    "approved_by": i.approved_by} for i in infos]))
        return
    if format != "table":
        raise typer.BadParameter(f"--format {format!r}: expected table or json")
    t = Table(box=box.SIMPLE_HEAD, padding=(0, 1), pad_edge=False, collapse_padding=True, show_edge=False)
    for name in ("id", "unit", "v", "created (UTC)"):
        t.add_column(name, no_wrap=True)
    t.add_column("procedures", min_width=16)
    t.add_column("approved by", min_width=9)
    for i in infos:
        t.add_row(i.id[:8], f"{i.serial} ({i.model})" if i.model and i.model not in i.serial else i.serial,
                  str(i.version), i.created[:16].replace("T", " "), ", ".join(i.procedures), i.approved_by or "")
    out.print(t)


def _triad_table(cal: CalibrationSet, triad: str) -> Table:
    tc = cal.triads[triad]
    unit = DISPLAY[triad]["bias"]
    t = Table(f"{triad}", "x", "y", "z", title=f"{triad} ({'hard iron' if triad == 'mag' else 'bias'} in "
                                                    f"{unit}, scale factor ppm, misalignment mrad)")
    b, bs = tc.model.bias, tc.sigma_of("bias")
    t.add_row("bias ± 1σ", *[f"{to_unit(b[i], unit):.4g} ± {_sig(bs[i], unit)}" for i in range(3)])
    m, ms = tc.model.scale_misalignment, tc.sigma_of("scale_misalignment")
    t.add_row("scale factor ± 1σ", *[f"{m[i, i] * 1e6:.1f} ± {_sig(ms[i, i], 'ppm')}" for i in range(3)])
    for i in range(3):
        t.add_row(f"misalignment {'xyz'[i]}-row (mrad)", *[("—" if i == j else f"{m[i, j] * 1e3:.3f} ± {_sig(ms[i, j], 'mrad')}")
                                                for j in range(3)])
    if np.any(tc.model.nonlinearity):
        t.add_row("nonlinearity (1/SI)", *[f"{v:.3g}" for v in tc.model.nonlinearity])
    if tc.model.g_sensitivity is not None:
        g = tc.model.g_sensitivity
        t.add_row("g-sensitivity diag (°/h/g)", *[f"{to_unit(g[i, i], 'deg/h') * 9.80665:.3g}" for i in range(3)])
    if tc.model.thermal is not None:
        t.add_row("thermal t_ref (°C)", f"{tc.model.thermal.t_ref_c:g}", "", "")
    if triad == "mag":
        t.add_row("field norm (µT)", f"{tc.field_norm_ut:.3f}", "", "")
    return t


def _sig(value: float, unit: str) -> str:
    if not np.isfinite(value):
        return "not observed"
    scale = {"ppm": 1e-6, "mrad": 1e-3}.get(unit)
    return f"{value / scale:.2g}" if scale else f"{to_unit(value, unit):.2g}"


@sets_app.command("show")
def show(ref: str = typer.Argument(..., help="Set id (or prefix) or calibration JSON file."),
         as_json: bool = typer.Option(False, "--json", help="Print the canonical JSON.")) -> None:
    """Show a calibration set in lab units (or as JSON)."""
    cal = load_set_ref(ref)
    if as_json:
        out.print_json(cal.to_json())
        return
    out.print(f"[bold]set {cal.id}[/]  unit {cal.unit.serial} ({cal.unit.model})  created {cal.created}")
    out.print(f"procedures: {', '.join(cal.provenance.procedures) or '—'}; sessions: "
              f"{len(cal.provenance.sessions)}; software {cal.provenance.software_version}")
    for triad in cal.triads:
        out.print(_triad_table(cal, triad))
    for triad, terms in cal.noise.items():
        t = Table("noise term", "x", "y", "z", title=f"{triad} noise")
        for term, values in terms.items():
            if term.endswith("_ci95"):
                continue
            unit = DISPLAY[triad].get("noise_white" if term in ("arw", "vrw") else term)
            t.add_row(f"{term} ({unit})" if unit else term,
                      *[fmt(v, unit) if unit else ("not observed" if v is None else f"{v:.3g}") for v in values])
        out.print(t)


@sets_app.command("diff")
def diff(old: str = typer.Argument(..., help="Older set: id or JSON file."),
         new: str = typer.Argument(..., help="Newer set: id or JSON file."),
         limit: int = typer.Option(40, help="Show at most this many rows.")) -> None:
    """Coefficient-by-coefficient changes, in units of their combined sigma."""
    a, b = load_set_ref(old), load_set_ref(new)
    rows = diff_sets(a, b)
    t = Table("triad", "field", "index", "old", "new", "change / σ")
    for r in rows[:limit]:
        flag = "bold red" if np.isfinite(r.change_in_sigma) and abs(r.change_in_sigma) > 3 else ""
        t.add_row(r.triad, r.field, str(r.index), f"{r.old:.6g}", f"{r.new:.6g}",
                  "σ not observed" if not np.isfinite(r.change_in_sigma) else f"{r.change_in_sigma:+.2f}",
                  style=flag)
    out.print(f"{len(rows)} coefficient(s) differ between {a.id[:8]} and {b.id[:8]}")
    out.print(t)


@sets_app.command("export")
def export(ref: str = typer.Argument(..., help="Set id (or prefix) or calibration JSON file."),
           format: str = typer.Option("json", "--format", "-f", help="Export format."),
           out_file: Path = typer.Option(None, "--out", "-o", help="Write to this file (default: stdout).")) -> None:
    """Export a set: json, yaml and the formats listed by `workbench sets formats`."""
    ex = exporter(format)
    result = ex.export(load_set_ref(ref))
    for item in result.dropped:
        out.print(f"[yellow]dropped:[/] {item}", highlight=False)
    if out_file is None:
        print(result.text, end="")
    else:
        atomic_write_text(out_file, result.text)
        out.print(f"wrote {out_file}")


@sets_app.command("formats")
def formats() -> None:
    """List the export formats."""
    for name, mod in sorted(exporters().items()):
        out.print(f"{name:12s} {mod.DESCRIPTION}")


@sets_app.command("approve")
def approve(ref: str = typer.Argument(..., help="Stored set id (or prefix)."),
            by: str = typer.Option(..., "--by", help="Who approves."),
            comment: str = typer.Option("", "--comment")) -> None:
    """Record an approval of a stored set (the set itself never changes)."""
    Store().approve(ref, by, comment)
    out.print(f"approved {ref} by {by}")


@sets_app.command("merge")
def merge_cmd(refs: list[str] = typer.Argument(..., help="Partial sets of one unit, oldest first."),
              out_file: Path = typer.Option(None, "--out", "-o", help="Also write the merged set here."),
              no_store: bool = typer.Option(False, "--no-store", help="Do not store the merged set.")) -> None:
    """Merge partial sets (e.g. accel from one procedure, gyro noise from another) into one."""
    merged = merge(*[load_set_ref(r) for r in refs])
    if out_file is not None:
        merged.save(out_file)
    if not no_store:
        version = Store().add_set(merged)
        out.print(f"stored {merged.id} as version {version} of {merged.unit.serial}")
    else:
        out.print(f"merged set {merged.id}")


def register(app: typer.Typer) -> None:
    app.add_typer(sets_app, name="sets")


@sets_app.command("stats")
def stats(grade: str = typer.Option(..., "--grade", help="Unit model (grade name) to summarise."),
          outliers_only: bool = typer.Option(False, "--outliers", help="Only coefficients with outliers.")) -> None:
    """Distribution of each coefficient across the units of a grade (latest set per unit), outliers flagged."""
    from workbench.fleet.stats import OUTLIER_Z, coefficient_stats

    store = Store()
    serials = [s for s, model in store.units() if model == grade]
    sets = [c for c in (store.latest(s) for s in serials) if c is not None]
    rows = coefficient_stats(sets)
    t = Table("triad", "field", "index", "n", "mean", "std", "median", "robust std", f"outliers (|z| > {OUTLIER_Z})",
              title=f"{grade}: {len(sets)} units")
    for r in rows:
        if outliers_only and not r.outliers:
            continue
        t.add_row(r.triad, r.field, str(r.index), str(r.n), f"{r.mean:.4g}", f"{r.std:.3g}", f"{r.median:.4g}",
                  f"{r.robust_std:.3g}", ", ".join(f"{s} (z={z:+.1f})" for s, _, z in r.outliers),
                  style="bold red" if r.outliers else "")
    out.print(t)
