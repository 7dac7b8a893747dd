"""``workbench sets``: list, show, diff, export, approve and merge calibration sets."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import typer
from rich import box
from rich.table import Table

from workbench.cli import err, out, styled
from workbench.registry import export_set, exporter, exporters

if TYPE_CHECKING:  # the set format, its coefficients and the store load when a command runs, not with the CLI
    from workbench.calset import CalibrationSet

sets_app = typer.Typer(no_args_is_help=True, help="Calibration sets: list, show, diff, export, approve, merge.")


def load_set_ref(ref: str, warn: bool = True) -> CalibrationSet:
    """A set from a calibration JSON file path or a stored set's id (or unique id prefix); a stored set
    breaking the id / serial / model rules (stored before them) is read, with a warning naming it unless
    not ``warn`` (a command about to refuse it says so in its one error line)."""
    from workbench.calset import CalibrationSet
    from workbench.errors import CalibrationFormatError
    from workbench.store import Store

    if not ref.strip():  # Path("") is the current folder
        raise CalibrationFormatError("empty set reference: give a set id (or prefix) or a calibration file")
    p = Path(ref)
    if p.suffix in (".json", ".yaml", ".yml") or p.exists():
        return CalibrationSet.load(p)
    cal = Store().get_set(ref)
    for problem in cal.name_problems(f"store set {cal.id}") if warn else []:
        _old_name_warning(problem)
    return cal


def _old_name_warning(problem: str) -> None:
    err.print(styled("warning:", "yellow", f" {problem} (stored before this rule: readable; exporting it or "
                                           "storing a set with it is refused)"), highlight=False, soft_wrap=True)


@sets_app.command("list")
def list_sets(unit: str = typer.Option(None, "--unit", help="Only this unit serial."),
              format: str = typer.Option("table", "--format", help="table | json")) -> None:
    """List stored calibration sets, newest first."""
    from workbench.store_read import list_sets

    url, infos = list_sets(unit)  # a SQLite store is read without loading SQLAlchemy
    if format == "json":
        out.print_json(json.dumps([{"id": i.id, "serial": i.serial, "model": i.model, "version": i.version,
                                    "created": i.created, "procedures": list(i.procedures),
                                    "approved_by": i.approved_by} for i in infos]))
        return
    if format != "table":
        raise typer.BadParameter(f"--format {format!r}: expected table or json")
    if not infos:
        out.print(f"no calibration sets {'' if unit is None else f'of unit {unit} '}in {url}")
    from workbench.confine import name_problems

    for i in infos:
        for problem in name_problems(i.id, i.serial, i.model, f"store set {i.id}"):
            _old_name_warning(problem)
        unit = f"{i.serial} ({i.model})" if i.model and i.model not in i.serial else i.serial
        out.print(styled(i.id[:8], "bold", f"  {unit}  v{i.version}  {i.created[:16].replace('T', ' ')} UTC  "
                                            f"approved by {i.approved_by or '—'}"))
        out.print(f"          procedures: {', '.join(i.procedures) or '—'}")


def _table(*columns: str, title: str | None = None) -> Table:
    """A compact table that fits 80 columns: no outer box, cells fold instead of being cut."""
    t = Table(box=box.SIMPLE_HEAD, padding=(0, 1), pad_edge=False, collapse_padding=True, show_edge=False,
              title=title, title_justify="left")
    for c in columns:
        t.add_column(c, overflow="fold")
    return t


def _triad_table(cal: CalibrationSet, triad: str) -> Table:
    """One row per coefficient (name, value ± 1σ, unit) in the lab units of ``workbench.units``."""
    from workbench.coefficients import TRIAD_TITLES, sigma_text, triad_rows, value_text

    t = _table("coefficient", "value ± 1σ", "unit", title=f"{TRIAD_TITLES[triad]} ({triad})")
    for r in triad_rows(cal, triad):
        sig = "± " + sigma_text(r.sigma) if r.observed else "(σ not observed)"
        t.add_row(r.name, f"{value_text(r.value)} {sig}", r.unit)
    return t


@sets_app.command("show")
def show(ref: str = typer.Argument(..., help="Set id (or prefix), or a calibration JSON / YAML file."),
         as_json: bool = typer.Option(False, "--json", help="Print the canonical JSON.")) -> None:
    """Show a calibration set in lab units (or as JSON)."""
    import numpy as np

    from workbench.coefficients import ci_text, noise_rows, thermal_reference

    cal = load_set_ref(ref)
    if as_json:
        out.print_json(cal.to_json())
        return
    out.print(f"set {cal.id}", style="bold")
    out.print(f"unit {cal.unit.serial} ({cal.unit.model}), created {cal.created}")
    out.print(f"procedures: {', '.join(cal.provenance.procedures) or '—'}; sessions: "
              f"{len(cal.provenance.sessions)}; software {cal.provenance.software_version}")
    from workbench.cli.run import print_forced

    print_forced(cal)
    for triad in cal.triads:
        out.print(_triad_table(cal, triad))
        ref_text = thermal_reference(cal, triad)
        if ref_text:
            out.print(f"  thermal: {ref_text}")
    rows = noise_rows(cal)
    if rows:
        t = _table("noise term", "axis", "value", "95 % interval", "unit", title="Noise (Allan variance)")
        for r in rows:
            t.add_row(f"{r.triad} {r.term}", r.axis, "not observed" if not np.isfinite(r.value) else f"{r.value:.4g}",
                      ci_text(r.ci95), r.unit)
        out.print(t)


@sets_app.command("diff")
def diff(old: str = typer.Argument(..., help="Older set: id or JSON file."),
         new: str = typer.Argument(..., help="Newer set: id or JSON file."),
         limit: int = typer.Option(40, help="Show at most this many rows.")) -> None:
    """Coefficient-by-coefficient changes, in units of their combined sigma."""
    from workbench.coefficients import element_name, element_unit, value_text
    from workbench.diff import (NOT_COMPARABLE, NOT_OBSERVED, NOT_OBSERVED_A, NOT_OBSERVED_B, ONLY_A, ONLY_B,
                                diff_sets)

    a, b = load_set_ref(old), load_set_ref(new)
    rows = diff_sets(a, b)
    t = _table("coefficient", "A (old)", "B (new)", "unit", "change / σ")
    for r in rows[:limit]:
        if r.field == "(triad)":
            t.add_row(f"{r.triad} (whole triad)", "absent" if r.state == ONLY_B else "present",
                      "absent" if r.state == ONLY_A else "present", "", r.state)
            continue
        if r.state == NOT_COMPARABLE:
            t.add_row(f"{r.triad} {r.field}", "", "", "", f"{r.state}: {r.note}")
            continue
        label, f = element_unit(r.triad, r.field, r.index)
        old_text = "not observed" if r.state in (NOT_OBSERVED_A, NOT_OBSERVED) else value_text(r.old / f)
        new_text = "not observed" if r.state in (NOT_OBSERVED_B, NOT_OBSERVED) else value_text(r.new / f)
        change = f"{r.change_in_sigma:+.2f}" if r.observed_in_both else r.state
        t.add_row(f"{r.triad} {element_name(r.field, r.index)}", old_text, new_text, label, change,
                  style="bold red" if r.observed_in_both and abs(r.change_in_sigma) > 3 else "")
    n_both = sum(r.observed_in_both for r in rows)
    out.print(f"{len(rows)} coefficient(s) differ between A = {a.id[:8]} and B = {b.id[:8]}: {n_both} observed in "
              f"both (change in σ = (B − A) / √(σ_A² + σ_B²)), {len(rows) - n_both} not observed in one of them "
              "or not comparable; values in the lab units of the unit column")
    out.print(t)
    if len(rows) > limit:
        out.print(f"… {len(rows) - limit} more (--limit)")


@sets_app.command("export")
def export(ref: str = typer.Argument(..., help="Set id (or prefix) or calibration JSON file."),
           format: str = typer.Option("json", "--format", "-f", help="Export format."),
           out_file: Path = typer.Option(None, "--out", "-o", help="Write to this file (default: stdout)."),
           force: bool = typer.Option(False, "--force", help="Export a set that fails a plausibility check "
                                                            "(the failed check goes into its notes).")) -> None:
    """Export a set: json, yaml and the formats listed by `workbench sets formats`.

    The set passes the plausibility gate first (:mod:`workbench.plausibility`): an implausible one
    (or one stored with ``--force`` past a failed check) is refused, nothing written, unless ``--force``.
    """
    from workbench.calset import atomic_write_text
    from workbench.plausibility import gate

    exporter(format)  # an unknown format is refused before the set is read
    result = export_set(gate(load_set_ref(ref, warn=False), force=force, what="export"), format)
    for item in result.dropped:
        out.print(styled("dropped:", "yellow", f" {item}"), highlight=False)
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
    from workbench.store import Store

    Store().approve(ref, by, comment)
    out.print(f"approved {ref} by {by}")


@sets_app.command("merge")
def merge_cmd(refs: list[str] = typer.Argument(..., help="Partial sets of one unit, oldest first."),
              out_file: Path = typer.Option(None, "--out", "-o", help="Also write the merged set here."),
              no_store: bool = typer.Option(False, "--no-store", help="Do not store the merged set."),
              force: bool = typer.Option(False, "--force", help="Keep a merged set that fails a plausibility check "
                                                               "(the failed check goes into its notes).")) -> None:
    """Merge partial sets (e.g. accel from one procedure, gyro noise from another) into one (plausibility-gated)."""
    from workbench.calset import merge
    from workbench.plausibility import gate
    from workbench.store import Store

    writes = out_file is not None or not no_store  # then a set breaking the serial rule is refused in one line
    merged = gate(merge(*[load_set_ref(r, warn=not writes) for r in refs]), force=force, what="merged calibration")
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
    from workbench.store import Store

    store = Store()
    units = store.units()
    serials = [s for s, model in units if model == grade]
    if not serials:  # a misspelt grade printed an empty table, exit 0
        from workbench.errors import StoreError
        from workbench.registry import unknown_hint

        raise StoreError(f"sets stats --grade {grade!r}: no unit of that model in {store.url} "
                         f"{unknown_hint(grade, sorted({m for _, m in units if m}))}")
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
