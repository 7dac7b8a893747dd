"""``workbench run``, ``analyze``, ``import`` and ``procedures``: record, analyse and import sessions."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

import typer
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

from workbench.cli import err, out, progress_bar, styled
from workbench.errors import ProcedureError, WorkbenchError
from workbench.options import declarations, option_rows, split, validate
from workbench.registry import procedure, procedures

if TYPE_CHECKING:  # sessions, analyses and the store load when a command runs, not with the CLI
    from workbench.procedure import ProcedureResult


def parse_options(items: list[str] | None, defaults: Mapping | None = None) -> dict:
    """``key=value`` pairs; values parsed as JSON where they parse (numbers, lists, true/false).

    With the procedure's ``defaults``, an option whose default is a number must be a finite
    number (``-o dwell_s=abc`` is a one-line error naming the option, not a traceback later); no
    value may hold a NaN or an infinity (``tilts_deg=[1e400]``), whatever its default.
    """
    opts = {}
    for item in items or []:
        if "=" not in item:
            raise WorkbenchError(f"--option {item!r}: expected key=value")
        key, value = item.split("=", 1)
        try:
            opts[key.strip()] = json.loads(value)
        except (json.JSONDecodeError, RecursionError):
            opts[key.strip()] = value
    for key, value in opts.items():
        default = (defaults or {}).get(key)
        if _is_number(default) and not (_is_number(value) and math.isfinite(value)):
            raise WorkbenchError(f"--option {key}={value!r}: expected a number (default {default!r})")
        if not _finite(value):  # JSON reads NaN, Infinity and 1e400 (inf): no option takes them
            raise WorkbenchError(f"--option {key}={value!r}: holds a number that is not finite")
    return opts


def _finite(value) -> bool:
    """Whether every number in ``value`` (a JSON value: nested lists and mappings) is finite."""
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, list):
        return all(map(_finite, value))
    if isinstance(value, dict):
        return all(map(_finite, value.values()))
    return True


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _progress_bar():
    return progress_bar(TextColumn("{task.description}", style="bold", markup=False), BarColumn(),
                        TextColumn("{task.completed}/{task.total} steps"),
                        TextColumn("{task.fields[step]}", markup=False), TimeRemainingColumn())


def _tracker(bar: Progress, name: str, total: int | None = None):
    """A progress callback for one recording; ``total`` steps shown from the start (known from the sequence)."""
    task = bar.add_task(name, total=total, step="")

    def progress(i: int, n: int, rec) -> None:
        bar.update(task, total=n, completed=i + 1, step=f"{rec.kind} {rec.label}".strip())
    return progress


@contextmanager
def _interruptible(session_dir: Path, procedure_name: str):
    """Turn Ctrl-C during a recording (the rig made safe by the runner) into exit code 130 and
    a command that resumes it."""
    try:
        yield
    except KeyboardInterrupt:
        from workbench.session import recorded_steps

        manifest = session_dir / "session.json"
        done = len(recorded_steps(session_dir, json.loads(manifest.read_text()))) if manifest.exists() else 0
        err.print(f"stopped: {done} step(s) complete and readable in {session_dir}; the rig was made safe "
                  f"(table stopped, chamber to its safe setpoint). Continue with: workbench run {procedure_name} "
                  f"--resume {session_dir}", highlight=False, soft_wrap=True)
        raise typer.Exit(130) from None


def _print_sequence(seq, limit: int = 12) -> None:
    rows = seq.describe()
    t = Table("#", "kind", "mount", "angle °", "rate °/s", "dwell s", "°C", "label",
              title=f"sequence {seq.name}: {len(rows)} steps, {seq.duration_s / 60:.1f} min planned")
    for r in rows[:limit]:
        t.add_row(str(r["index"]), r["kind"], r["mount"], f"{r['table_angle_deg']:g}", f"{r['table_rate_dps']:g}",
                  f"{r['duration_s']:g}", "" if r["temperature_c"] is None else f"{r['temperature_c']:g}", r["label"])
    if len(rows) > limit:
        t.add_row("…", f"{len(rows) - limit} more", "", "", "", "", "", "")
    out.print(t)


def _print_result(result: ProcedureResult, out_dir: Path | None) -> None:
    for line in result.summary:
        out.print(line, highlight=False)
    for w in result.warnings:
        out.print(styled("warning:", "yellow", f" {w}"), highlight=False)
    print_forced(result.calibration)
    if out_dir is not None:
        out.print(f"results in {out_dir} (result.json{', calibration.json' if result.calibration else ''}, figures/)",
                  soft_wrap=True)  # a path is never broken across lines


def print_forced(cal) -> None:
    """Say so when a calibration was kept past failed plausibility checks (``--force``)."""
    from workbench.plausibility import forced_failures

    for text in forced_failures(cal) if cal is not None else []:
        out.print(styled("forced past a failed plausibility check:", "bold red", f" {text}"), highlight=False,
                  soft_wrap=True)


def _load_calibration(ref: str | None, proc):
    """The set ``--calibration`` names (None without one), read before anything is recorded: a procedure
    ``proc`` whose analysis takes no calibration (not a validation) refuses it, so a mistyped command
    is one line before the rig moves, not after the recording."""
    if ref is None:
        return None
    if not _needs_cal(proc):
        raise ProcedureError(f"{proc.NAME}: --calibration is for validations; {proc.NAME} takes none "
                             "(it produces a calibration)")
    from workbench.cli.sets import load_set_ref

    return load_set_ref(ref)


def _default_out(name: str, serial: str) -> Path:
    """``runs/<procedure>-<serial>-<UTC time>``; the serial must be a safe path component."""
    from workbench.confine import safe_component

    return Path("runs") / f"{name}-{safe_component(serial, 'serial')}-{datetime.now(UTC).strftime('%Y%m%dT%H%M%S')}"


def _out_folder(value: Path | None) -> Path | None:
    """``--out`` of a run: a folder to create or fill, never an existing file."""
    if value is not None and value.exists() and not value.is_dir():
        raise typer.BadParameter(f"{value} is a file; --out names a folder")
    return value


def _safe_serial(value: str | None) -> str | None:
    from workbench.confine import safe_component

    return None if value is None else safe_component(value, "--serial", typer.BadParameter)


def run(procedure_name: str = typer.Argument(..., metavar="PROCEDURE", help="A procedure name, or 'campaign'."),
        unit: str = typer.Option("industrial_mems", "--unit",
                                  help="Unit grade fixture (fixtures/units/*.yaml) or grade name."),
        rig: str = typer.Option("sim", "--rig", help="'sim' or a rig configuration file (fixtures/rigs/*.yaml)."),
        seed: int = typer.Option(1, "--seed", min=0, help="Seed of the simulated unit and its noise."),
        serial: str = typer.Option(None, "--serial", callback=_safe_serial,
                                   help="Serial of the unit under test (on a real rig; default: the simulated "
                                        "unit's, <grade>-<seed>); letters, digits and . _ + -."),
        out_dir: Path = typer.Option(None, "--out", callback=_out_folder,
                                     help="Output folder (default runs/<procedure>-<serial>-<time>)."),
        resume: Path = typer.Option(None, "--resume", help="Continue an interrupted session folder."),
        option: list[str] = typer.Option(None, "--option", "-o", help="Option key=value of the sequence or the analysis (repeatable; "
                                   "'workbench procedures PROC' lists them; a campaign takes PROC.key=value)."),
        calibration: str = typer.Option(None, "--calibration", help="Calibration set (id or JSON) for validations."),
        no_store: bool = typer.Option(False, "--no-store", help="Leave the store untouched."),
        dry_run: bool = typer.Option(False, "--dry-run", help="Show the sequence and stop."),
        no_figures: bool = typer.Option(False, "--no-figures", help="Draw no figures (batch work; results and "
                                                                     "calibration sets as usual)."),
        force: bool = typer.Option(False, "--force", help="Store a calibration that fails a plausibility check, "
                                                          "with the failed check in the set's notes.")) -> None:
    """Record a procedure's sequence on the rig, analyse it, store the result and print a summary."""
    from workbench.grades import draw_unit, load_spec
    from workbench.jobs import record_procedure, resume_procedure, run_campaign
    from workbench.rigconfig import check_plan, load_rig_config
    from workbench.store import Store

    store = None if no_store or dry_run else Store()
    if resume is not None:
        from workbench.jobs import recorded_analysis_options

        with _interruptible(resume, procedure_name), _progress_bar() as bar:
            session = resume_procedure(resume, _tracker(bar, "resume"))
        proc = procedure(session.procedure)
        _analyse_and_report(proc, session, resume.parent if resume.name == "session" else resume, store, calibration,
                            {**recorded_analysis_options(session), **parse_options(option)}, not no_figures, force)
        return
    spec = load_spec(unit)
    cfg = load_rig_config(rig)
    truth = draw_unit(spec, seed, serial=serial)
    if procedure_name == "campaign":
        if calibration is not None:
            raise ProcedureError("campaign: --calibration is for validations; a campaign produces the calibration")
        campaign_options = _campaign_options(parse_options(option))
        out_dir = out_dir or _default_out("campaign", truth.serial)
        out.print(f"campaign for {truth.serial} ({spec.name}) on {cfg.name}, seed {seed} -> {out_dir}", soft_wrap=True)
        plans = _campaign_plans(spec, cfg, campaign_options)  # every plan within the rig's limits first
        if dry_run:
            for seq in plans.values():
                _print_sequence(seq)
            return
        totals = {name: len(seq.expand()) for name, seq in plans.items()}
        with _progress_bar() as bar:
            res = run_campaign(spec, truth, cfg, seed, out_dir, store,
                               lambda name: _tracker(bar, name, totals.get(name)), options=campaign_options,
                               figures=not no_figures, force=force)
        for name, r in res.results.items():
            out.print(name, style="bold")
            _print_result(r, out_dir / name)
        out.print(styled("calibration set", "bold green", f" {res.calibration.id} -> {out_dir / 'calibration.json'}"),
                  soft_wrap=True)
        out.print(f"figures {'not drawn' if no_figures else f'under {out_dir}/*/figures'}; "
                  f"store: {store.url if store else 'not used (--no-store)'}",
                  soft_wrap=True)
        return
    proc = procedure(procedure_name)
    # a number-valued option must be a number (one that also takes a word, e.g. 'auto', is checked below)
    options = parse_options(option, {o.name: o.default for o in declarations(proc) if not o.words})
    if getattr(proc, "DRIVE", False):  # recorded on the simulated vehicle, not on the turntable
        _run_drive(proc, spec, truth, cfg, seed, out_dir, options, store, calibration, dry_run, not no_figures, force)
        return
    seq_options, analysis_options = split(proc, options)  # refuses a misspelt option before anything runs
    cal = _load_calibration(calibration, proc)
    seq = proc.sequence(spec, **seq_options)
    _print_sequence(seq)
    # the limits the rig checks before anything moves, checked before the progress bar starts
    check_plan(seq.expand(), cfg, spec.sample_rate_hz)
    if dry_run:
        out.print(f"within the limits of rig {cfg.name}")
        return
    out_dir = out_dir or _default_out(proc.NAME, truth.serial)
    if cal is None and _needs_cal(proc):
        cal = _calibrate_first(spec, truth, cfg, seed, out_dir)
    with _interruptible(out_dir / "session", proc.NAME), _progress_bar() as bar:
        session = record_procedure(proc, spec, truth, cfg, seed, out_dir / "session", options,
                                   _tracker(bar, proc.NAME, len(seq.expand())))
    _analyse_and_report(proc, session, out_dir, store, cal, analysis_options, not no_figures, force)


def _campaign_plans(spec, cfg, campaign_options: dict[str, dict]) -> dict:
    """The sequence of each campaign procedure that applies to grade ``spec``, each checked against
    the limits of rig ``cfg`` (RigLimitError naming the step), so a refusal comes before any progress
    bar or recording; options naming a procedure the campaign does not run are refused."""
    from workbench.jobs import applies
    from workbench.registry import campaign_procedures
    from workbench.rigconfig import check_plan

    procs = [p for p in campaign_procedures(set(spec.triads)) if applies(p, spec)]
    idle = sorted(set(campaign_options) - {p.NAME for p in procs})
    if idle:
        raise ProcedureError(f"campaign: -o {idle[0]}.*: {idle[0]} is not in the campaign of grade {spec.name} "
                             f"(campaign: {', '.join(p.NAME for p in procs)})")
    plans = {}
    for p in procs:
        plans[p.NAME] = p.sequence(spec, **split(p, campaign_options.get(p.NAME))[0])
        check_plan(plans[p.NAME].expand(), cfg, spec.sample_rate_hz)
    return plans


def _campaign_options(options: dict) -> dict[str, dict]:
    """``-o PROC.key=value`` of a campaign -> {procedure: {key: value}}, each checked against its procedure."""
    by_proc: dict[str, dict] = {}
    for key, value in options.items():
        name, dot, opt = key.partition(".")
        if not dot:
            raise ProcedureError(f"campaign: option {key!r} must name its procedure, e.g. -o multiposition.{key}=...")
        by_proc.setdefault(name, {})[opt] = value
    for name, opts in by_proc.items():
        split(procedure(name), opts)
    return by_proc


def _run_drive(proc, spec, truth, cfg, seed: int, out_dir: Path | None, options: dict, store, calibration,
               dry_run: bool, figures: bool = True, force: bool = False) -> None:
    """Drive the simulated vehicle for a land-navigation validation, then analyse the drive."""
    from workbench.procedure import run_analysis

    seq_options, analysis_options = split(proc, options)  # refuses a misspelt option before anything runs
    if cfg.driver != "sim":
        raise ProcedureError(f"{proc.NAME}: a drive is simulated (--rig sim) or imported (workbench analyze)")
    cal = _load_calibration(calibration, proc)
    out.print(f"{proc.NAME}: simulated drive of {truth.serial} ({spec.name}), seed {seed}")
    if dry_run:
        return
    out_dir = out_dir or _default_out(proc.NAME, truth.serial)
    if cal is None:
        cal = _calibrate_first(spec, truth, cfg, seed, out_dir)
    session = proc.record_drive(truth, seed, out_dir / "session", **seq_options)
    result = run_analysis(proc, session, {**analysis_options, "calibration": cal}, out_dir, store, figures, force)
    _print_result(result, out_dir)


def _needs_cal(proc) -> bool:
    from workbench.jobs import needs_calibration

    return needs_calibration(proc)


def _calibrate_first(spec, truth, cfg, seed, out_dir: Path):
    """On the simulated rig, calibrate the unit with the calibrating procedures before a validation."""
    from workbench.jobs import CALIBRATING, run_campaign

    if cfg.driver != "sim":
        raise ProcedureError("this validation needs --calibration SET on a real rig")
    out.print(f"calibrating the simulated unit first ({', '.join(CALIBRATING)})")
    with _progress_bar() as bar:
        res = run_campaign(spec, truth, cfg, seed, out_dir / "calibration", None, lambda n: _tracker(bar, n),
                           only=list(CALIBRATING), options=CALIBRATING)
    return res.calibration


def _analyse_and_report(proc, session, out_dir: Path, store, calibration, analysis_options=None,
                        figures: bool = True, force: bool = False) -> None:
    from workbench.procedure import run_analysis

    options = dict(analysis_options or {})  # checked again by the procedure's analyze()
    if calibration is not None:
        options["calibration"] = _load_calibration(calibration, proc) if isinstance(calibration, str) else calibration
    result = run_analysis(proc, session, options, out_dir, store, figures, force)
    _print_result(result, out_dir)
    if result.calibration is not None:
        out.print(f"calibration set {result.calibration.id}"
                  f"{' stored in ' + store.url if store else ''}")


def analyze(procedure_name: str = typer.Argument(..., metavar="PROCEDURE"),
            session_dir: Path = typer.Argument(..., help="Session folder (session.json + samples)."),
            out_file: Path = typer.Option(None, "--out", help="Also write the calibration set (or result) here."),
            no_store: bool = typer.Option(False, "--no-store", help="Leave the store untouched."),
            option: list[str] = typer.Option(None, "--option", "-o", help="Analysis option key=value."),
            calibration: str = typer.Option(None, "--calibration", help="Calibration set for validations."),
            figures: Path = typer.Option(None, "--figures", help="Write result.json and figures/ into this folder."),
            no_figures: bool = typer.Option(False, "--no-figures", help="With --figures: write result.json only."),
            force: bool = typer.Option(False, "--force", help="Store a calibration that fails a plausibility check, "
                                                             "with the failed check in the set's notes.")
            ) -> None:
    """Analyse any session in the workbench format and store its calibration set (or result)."""
    from workbench.procedure import run_analysis
    from workbench.session import load_session
    from workbench.store import Store

    proc = procedure(procedure_name)
    options = parse_options(option)
    validate(proc, options)  # a misspelt option is refused before the session is read
    cal = _load_calibration(calibration, proc)
    session = load_session(session_dir)
    if cal is not None:
        options["calibration"] = cal
    result = run_analysis(proc, session, options, figures, None if no_store else Store(), not no_figures, force)
    if out_file is not None:
        from workbench.calset import atomic_write_text
        from workbench.procedure import result_json

        if result.calibration is not None and out_file.name != "result.json":
            result.calibration.save(out_file)
        else:
            atomic_write_text(out_file, result_json(result))
        out.print(f"wrote {out_file}")
    _print_result(result, figures)


def import_cmd(profile: Path = typer.Argument(..., help="Import profile (YAML)."),
               data_file: Path = typer.Argument(..., metavar="DATA", help="The recording to import: its file "
                                                "(CSV or Parquet), or its folder for a profile with streams."),
               out_dir: Path = typer.Option(..., "--out", help="Session folder to create.")) -> None:
    """Import another tool's recording into a session folder through an import profile."""
    from workbench.importer import import_file
    from workbench.importers.summary import summary_lines

    session = import_file(profile, data_file, out_dir)
    for line in summary_lines(session.options["import"]):
        out.print(line, soft_wrap=True)
    out.print(f"imported {len(session.samples)} samples, {len(session.steps)} steps -> {out_dir}")
    t = Table("#", "kind", "label", "t_start s", "t_end s")
    for s in session.steps:
        t.add_row(str(s.index), s.kind, s.label, f"{s.t_start:.2f}", f"{s.t_end:.2f}")
    out.print(t)


def list_procedures(name: str = typer.Argument(None, metavar="[PROCEDURE]",
                                               help="Show this procedure's options.")) -> None:
    """List the procedures, or the declared options of one (stage, type, unit, default, allowed values)."""
    if name is not None:
        proc = procedure(name)
        t = Table(title=f"{proc.NAME}: {proc.TITLE}")
        t.add_column("option", no_wrap=True)
        for col in ("stage", "type", "unit", "default", "allowed", "help"):
            t.add_column(col)
        for r in option_rows(proc):
            t.add_row(r["name"], r["stage"], r["type"], r["unit"], r["default"], r["allowed"], r["help"])
        out.print(t)
        return
    t = Table("procedure", "title", "triads", "campaign", "options")
    for pname, p in sorted(procedures().items()):
        t.add_row(pname, p.TITLE, ", ".join(p.TRIADS), str(p.CAMPAIGN_ORDER or "—"),
                  ", ".join(o["name"] for o in option_rows(p)))
    out.print(t)


def register(app: typer.Typer) -> None:
    app.command("run")(run)
    app.command("analyze")(analyze)
    app.command("import")(import_cmd)
    app.command("procedures")(list_procedures)
