"""Jobs: record a procedure's sequence on a rig and analyse it; the campaign of all procedures.

These are the orchestration the command line, the dashboard and batch runs share:
:func:`simulate` (a sequence on the simulated rig, the one-call entry point for tests and
demos), :func:`open_rig` (simulated or real), :func:`record_procedure`, :func:`resume_procedure` and
:func:`run_campaign`, which runs every procedure that applies to the unit in campaign order
and merges their calibration sets into one.
"""

from __future__ import annotations

import inspect
import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np

from workbench import units
from workbench.calset import CalibrationSet, Unit, atomic_write_text, merge
from workbench.errors import ProcedureError, WorkbenchError
from workbench.options import declarations, rig_options, split, validate
from workbench.plausibility import gate
from workbench.procedure import ProcedureResult
from workbench.registry import campaign_procedures
from workbench.rigconfig import RigConfig, load_rig_config
from workbench.runner import Progress, record, reopen, rig_state_for_resume, start
from workbench.session import Session

if TYPE_CHECKING:
    from workbench.sim.imperfections import Imperfections

# run first when a validation needs a set, with their options (a shorter Allan record)
CALIBRATING = {"multiposition": {}, "rate": {}, "magnetometer": {}, "allan": {"duration_s": 1800.0, "soak": False}}


def open_rig(cfg: RigConfig, truth, seed: int, state=None, imperfections=None):
    """A rig for ``cfg``: the simulated rig (driving ``truth``, with ``imperfections``, a
    :class:`workbench.sim.imperfections.Imperfections` or None), or a real driver."""
    if cfg.driver == "sim":
        from workbench.sim.rig import SimRig

        return SimRig(cfg, truth, seed, state, imperfections=imperfections)
    if imperfections is not None:
        raise ProcedureError(f"rig {cfg.name}: imperfections are an option of the simulated rig only "
                             "(a real unit brings its own)")
    try:
        from workbench.drivers.rig import open_real_rig
    except ImportError:
        raise WorkbenchError(f"rig {cfg.name}: driver {cfg.driver!r} is not available in this version") from None
    return open_real_rig(cfg, truth, seed, state)


def simulate(sequence, unit, seed: int, out_dir: str | Path | None = None, rig=None, site=None,
             procedure: str | None = None, progress=None, imperfections=None):
    """Record ``sequence`` on the simulated rig; returns ``(Session, UnitTruth)``.

    ``unit``: a grade name or fixture path, a ``SensorSpec`` or a ``UnitTruth`` (drawn from the
    spec with ``seed`` when not already a truth). ``rig``: a ``RigConfig``, a rig-config name or
    path, or None for ``fixtures/rigs/sim.yaml``. ``site``: a ``workbench.session.Site`` that
    replaces the rig's site. ``out_dir``: a folder for the session (with ``truth.json``), or None
    to keep it in memory. The same ``seed`` gives the same samples. ``imperfections``: a
    :class:`workbench.sim.imperfections.Imperfections` (warm-up, turn-on repeatability, noise vs
    temperature), or None for a unit that follows its model exactly.
    """
    from workbench.grades import SensorSpec, UnitTruth, draw_unit, load_spec
    from workbench.sim import write_truth
    from workbench.sim.rig import SimRig

    if isinstance(unit, UnitTruth):
        truth = unit
    else:
        spec = unit if isinstance(unit, SensorSpec) else load_spec(unit)
        truth = draw_unit(spec, seed)
    cfg = rig if isinstance(rig, RigConfig) else load_rig_config(rig or "sim")
    if site is not None:
        cfg = replace(cfg, site=site)
    sim = SimRig(cfg, truth, seed, imperfections=imperfections)
    rec = start(sequence, sim, Unit(truth.serial, truth.model), procedure or sequence.name,
                Path(out_dir) if out_dir is not None else None, extra={"seed": int(seed)})
    if out_dir is not None:
        write_truth(Path(out_dir), truth, cfg, seed)
    return record(rec, sim, progress), truth


def sim_imperfections(spec, rig: Mapping) -> Imperfections | None:
    """The simulated rig's imperfections from the rig-stage options (:data:`workbench.options.RIG_OPTIONS`,
    lab units): the grade's imperfections block for the groups named, the table errors in degrees;
    None when everything is off (the rig then follows the model exactly)."""
    from workbench.sim.imperfections import Imperfections

    groups = str(rig.get("imperfections", "off")).strip()
    names = groups if groups in ("off", "all") else [g.strip() for g in groups.split(",") if g.strip()]
    table = {k: np.radians(float(rig.get(f"{k}_deg", 0.0) or 0.0))
             for k in ("table_indexing_error", "table_wobble", "table_axis_tilt")}
    if names == "all" and not spec.imperfections:
        raise ProcedureError(f"imperfections=all: grade {spec.name} has no imperfections block")
    imp = Imperfections.from_spec(spec, names, **table)
    return imp if imp.unit or imp.table else None


def applies(proc: ModuleType, spec) -> bool:
    """Whether procedure ``proc`` applies to a unit of grade ``spec`` (its triads, its own test)."""
    if not set(proc.TRIADS) <= set(spec.triads):
        return False
    return bool(proc.applies(spec)) if hasattr(proc, "applies") else True


def needs_calibration(proc: ModuleType) -> bool:
    """Whether the procedure's analysis takes a ``calibration`` set (a validation run)."""
    return "calibration" in inspect.signature(proc.analyze).parameters


def record_procedure(proc: ModuleType, spec, truth, cfg: RigConfig, seed: int, out_dir: Path | None,
                     options: Mapping | None = None, progress: Progress | None = None) -> Session:
    """Record ``proc``'s sequence for a unit of grade ``spec`` on the rig ``cfg``.

    ``options`` may hold options of both stages (checked by :func:`workbench.options.split`);
    the sequence gets its own, the analysis ones are recorded in the manifest
    (``analysis_options``, read back by :func:`recorded_analysis_options`).
    """
    if not set(proc.TRIADS) <= set(spec.triads):
        raise ProcedureError(f"procedure {proc.NAME} needs triads {', '.join(proc.TRIADS)}; "
                             f"grade {spec.name} has {', '.join(spec.triads)}")
    seq_options, analysis_options = split(proc, options)
    sequence = proc.sequence(spec, **validate(proc, seq_options, "sequence"))
    rig_opts = rig_options(proc, options)
    rig_given = {k: v for k, v in dict(options or {}).items() if k in rig_opts.given}
    rig = open_rig(cfg, truth, seed, imperfections=sim_imperfections(spec, rig_opts))
    # the analysis options given with the recording travel in the manifest, for a resumed run
    rec = start(sequence, rig, Unit(truth.serial, truth.model), proc.NAME, out_dir,
                extra={"seed": int(seed), "grade": spec.name, "rig_config": str(cfg.path or cfg.name),
                       **({"analysis_options": analysis_options} if analysis_options else {}),
                       **({"rig_options": rig_given} if rig_given else {})})
    if out_dir is not None and cfg.driver == "sim":
        from workbench.sim import write_truth

        write_truth(Path(out_dir), truth, cfg, seed)
    return record(rec, rig, progress)


def recorded_analysis_options(session: Session | Path) -> dict:
    """The analysis options recorded with a session by :func:`record_procedure` (empty if none)."""
    path = Path(session.path if isinstance(session, Session) else session) / "session.json"
    try:
        return dict(json.loads(path.read_text()).get("analysis_options") or {})
    except (OSError, ValueError):
        return {}


def resume_procedure(out_dir: Path, progress: Progress | None = None) -> Session:
    """Continue an interrupted recording from its first incomplete step.

    A recording that had completed (the run was interrupted in its analysis, after the last step
    reached the disk) is returned as it is, so the resume hint finishes the job: it is analysed.
    """
    from workbench.grades import UnitTruth

    manifest = Path(out_dir) / "session.json"
    if manifest.exists() and json.loads(manifest.read_text()).get("complete"):
        from workbench.session import load_session

        return load_session(out_dir)
    rec = reopen(out_dir)
    m = rec.manifest
    cfg = load_rig_config(m.get("rig_config") or "sim")
    truth_file = Path(out_dir) / "truth.json"
    if cfg.driver == "sim":
        if not truth_file.exists():
            raise WorkbenchError(f"{out_dir}: no truth.json; a simulated session cannot be resumed without it")
        truth = UnitTruth.from_dict(json.loads(truth_file.read_text())["unit"], str(truth_file))
    else:
        truth = None
    # the saved rig state carries the noise processes: the resumed part continues them exactly, and
    # the rig options recorded with the session switch the same imperfections on
    imperfections = None
    if m.get("rig_options") and cfg.driver == "sim":
        from workbench.grades import load_spec

        imperfections = sim_imperfections(load_spec(m.get("grade") or truth.model), m["rig_options"])
    rig = open_rig(cfg, truth, int(m.get("seed", 0)), rig_state_for_resume(rec), imperfections)
    return record(rec, rig, progress)


# analysis options a campaign procedure takes from the noise block of an earlier one (the Allan
# record): option name -> (triad, noise term, lab unit of the option)
NOISE_OPTIONS = {"accel_bias_instability_mg": ("accel", "bias_instability", "mg"),
                 "gyro_bias_instability_deg_h": ("gyro", "bias_instability", "deg/h"),
                 "accel_rrw_m_s_h_sqrt_h": ("accel", "rrw", "m/s/h/sqrt(h)"),
                 "gyro_rrw_deg_h_sqrt_h": ("gyro", "rrw", "deg/h/sqrt(h)")}


def noise_options(proc: ModuleType, sets: list[CalibrationSet]) -> dict:
    """The :data:`NOISE_OPTIONS` ``proc`` takes, from the first of ``sets`` with that noise term.

    E.g. the bias instability B of the Allan record sets the floor of the multi-position bias
    sigma (``workbench.analysis.position_check``) and its rate random walk K the wander in a
    thermal sweep's bias at t_ref. On an axis where the record did not observe the term, the
    upper end of its 95 % interval (what the data allow) is used: uncertainties stay on the
    safe side.
    """
    out = {}
    for key, (triad, term, unit) in NOISE_OPTIONS.items():
        if key not in {o.name for o in declarations(proc)}:
            continue
        for s in sets:
            value = s.noise_term(triad, term)
            bound = np.array([np.nan if b is None else b[1] for b in
                              s.noise.get(triad, {}).get(f"{term}_ci95") or [None] * 3], float)
            value = np.where(np.isfinite(value), value, bound)
            if np.isfinite(value).all():
                out[key] = units.to_unit(value, unit).tolist()
                break
    return out


def noise_options_known(proc: ModuleType, earlier: list[ProcedureResult | None]) -> bool:
    """Whether :func:`noise_options` of ``proc`` is decided by the ``earlier`` results known so far.

    ``earlier``: the results of the procedures before ``proc`` in campaign order, None for one
    not analysed yet. Decided when every noise option ``proc`` declares is found in the sets
    before the first unknown result (the first set with a term gives it), or when all are known.
    """
    wanted = {k for k in NOISE_OPTIONS if k in {o.name for o in declarations(proc)}}
    sets: list[CalibrationSet] = []
    for r in earlier:
        if wanted <= set(noise_options(proc, sets)):
            return True
        if r is None:
            return False
        if r.calibration is not None:
            sets.append(r.calibration)
    return True


@dataclass
class CampaignResult:
    """The merged calibration set of a campaign and the result of each procedure.

    ``usage``: per procedure and phase (``record``, ``analyse``, ``figures``), the wall and CPU
    seconds it took and the peak resident memory (bytes) of the process that ran it.
    ``worker_busy_s``: per worker process, the wall seconds it spent running jobs (empty when
    everything ran in order in this process); against the campaign's wall time, its idle time.
    """

    calibration: CalibrationSet
    results: dict[str, ProcedureResult] = field(default_factory=dict)
    out_dir: Path | None = None
    usage: dict[str, dict[str, dict]] = field(default_factory=dict)
    worker_busy_s: list[float] = field(default_factory=list)


@dataclass
class CampaignPlan:
    """The campaign's procedures and what each runs with; the steps :mod:`workbench.campaign_schedule` runs.

    Procedure ``k`` is recorded with seed ``seed + 101 (k + 1)`` into ``out_dir/<name>/session``,
    analysed with its analysis options (the chamber's ambient as ``t_ref_c``, the noise terms of
    the procedures before it, the options given) and its outputs written to ``out_dir/<name>``.
    Each step depends only on its arguments, so the steps of different procedures may run in any
    order or in different processes and give the same files.
    """

    procs: list[ModuleType]
    spec: object
    truth: object
    cfg: RigConfig
    seed: int
    out_dir: Path
    given: dict[str, tuple[dict, dict]]
    figures: bool = True
    force: bool = False

    def name(self, k: int) -> str:
        """The name of procedure ``k``."""
        return self.procs[k].NAME

    def _declared(self, k: int) -> set[str]:
        return {o.name for o in declarations(self.procs[k])}

    def sequence_options(self, k: int) -> dict:
        """Sequence options of procedure ``k``: a hold at a set temperature runs at the ambient."""
        ambient = self.cfg.chamber.initial_c
        return {**({"temperature_c": ambient} if "temperature_c" in self._declared(k) else {}), **self.given[self.name(k)][0]}

    def planned_s(self, k: int) -> float:
        """Planned duration of procedure ``k``'s sequence, s (the longest is started first)."""
        proc = self.procs[k]
        seq = proc.sequence(self.spec, **validate(proc, self.sequence_options(k), "sequence"))
        return float(sum(p.duration_s for p in seq.expand()))

    def preload(self) -> None:
        """Import what recording needs (the simulated rig, Parquet) and load what drawing figures needs,
        once, before worker processes fork."""
        import pyarrow.pandas_compat  # noqa: F401 - frames to Arrow tables
        import pyarrow.parquet  # noqa: F401 - the step parts and the samples file

        if self.cfg.driver == "sim":
            import workbench.sim.imperfections  # noqa: F401 - the lab imperfections the rig is opened with
            import workbench.sim.rig  # noqa: F401
            import workbench.sim.sensor  # noqa: F401 - the rig's sensor model, imported when it starts
            from workbench.sim.filters import load_kernels
            from workbench.sim.noise import flicker_design

            load_kernels()
            flicker_design(1.0 / self.truth.sample_rate_hz)  # the noise filter, designed once for every recording
        if self.figures:
            from workbench.plots.pool import prepare_drawing

            prepare_drawing()

    def record(self, k: int, progress: Progress | None = None) -> Session:
        """Record procedure ``k``'s sequence."""
        return record_procedure(self.procs[k], self.spec, self.truth, self.cfg, self.seed + 101 * (k + 1),
                                self.out_dir / self.name(k) / "session", self.sequence_options(k), progress)

    def ready(self, k: int, earlier: list[ProcedureResult | None]) -> bool:
        """Whether procedure ``k``'s analysis options are decided by the ``earlier`` results (None: not yet)."""
        return noise_options_known(self.procs[k], earlier)

    def analysis_options(self, k: int, earlier: list[ProcedureResult | None]) -> dict:
        """Analysis options of procedure ``k``, from the results of the procedures before it."""
        proc = self.procs[k]
        # a model with a reference temperature refers to the ambient the other procedures ran at,
        # so that its bias and scale factor at t_ref merge consistently with theirs
        analysis = {"t_ref_c": self.cfg.chamber.initial_c} if "t_ref_c" in self._declared(k) else {}
        analysis.update(noise_options(proc, [r.calibration for r in earlier if r is not None and r.calibration is not None]))
        analysis.update(self.given[proc.NAME][1])
        validate(proc, analysis, "analysis")  # the noise options pass the declared-option check too
        return analysis

    def analyse(self, k: int, session: Session, options: Mapping) -> ProcedureResult:
        """Analyse procedure ``k``'s session; write ``result.json`` and ``calibration.json``."""
        from workbench.procedure import analysed, write_outputs

        result = analysed(self.procs[k], session, options, self.force)
        write_outputs(result, self.out_dir / self.name(k))
        return result

    def draw(self, k: int, result: ProcedureResult) -> dict:
        """Procedure ``k``'s figures ({name: Figure}, not saved yet; empty without figures)."""
        proc = self.procs[k]
        return dict(proc.figures(result)) if self.figures and hasattr(proc, "figures") else {}

    def save(self, k: int, figures: Mapping, workers: int | None = None) -> None:
        """Save (and close) ``figures`` of procedure ``k`` into ``out_dir/<name>/figures``."""
        from workbench.plots.pool import save_figures

        if figures:
            save_figures(figures, self.out_dir / self.name(k) / "figures", workers=workers)


def run_campaign(spec, truth, cfg: RigConfig, seed: int, out_dir: Path, store=None,
                 progress_for: Callable[[str], Progress | None] | None = None,
                 only: list[str] | None = None, options: Mapping[str, Mapping] | None = None,
                 figures: bool = True, force: bool = False, workers: int | None = None) -> CampaignResult:
    """Run every calibration procedure that applies to the unit, in order, and merge their sets.

    Each procedure records into ``out_dir/<name>/session`` and writes its results and figures to
    ``out_dir/<name>``; the merged set goes to ``out_dir/calibration.json`` and, with a
    ``store``, into the store (per-procedure results too), after everything succeeded.
    ``options`` maps a procedure name to its options (sequence and analysis, checked by
    :func:`workbench.options.split` before anything is recorded; defaults otherwise). Holds at a
    set temperature run at the chamber's ambient, models with a reference temperature refer to
    it, and later procedures take the noise terms of earlier ones (:func:`noise_options`; they
    go through the procedure's declared-option check like any other); options given explicitly
    win. ``campaign.json`` lists the analysis options so set. ``figures=False`` draws none.
    Every procedure's set and the merged set pass the plausibility gate
    (:mod:`workbench.plausibility`; ``force`` keeps a failed one with the check in its notes).
    ``workers``: processes to run the procedures in (default: one per usable CPU,
    :func:`workbench.workers.usable_workers`); the files are the same for any number.
    """
    from workbench.campaign_schedule import run_plan

    procs = [p for p in campaign_procedures(set(spec.triads)) if applies(p, spec) and not needs_calibration(p)]
    if only:
        procs = [p for p in procs if p.NAME in only]
    if not procs:
        raise ProcedureError(f"no campaign procedure applies to grade {spec.name}")
    given = {p.NAME: split(p, (options or {}).get(p.NAME)) for p in procs}  # refuse bad options up front
    out_dir = Path(out_dir)
    plan = CampaignPlan(procs, spec, truth, cfg, seed, out_dir, given, figures, force)
    done = run_plan(plan, progress_for, workers)
    results = {plan.name(k): done.results[k] for k in range(len(procs))}
    sets = [r.calibration for r in results.values() if r.calibration is not None]
    if not sets:
        raise ProcedureError("the campaign produced no calibration set")
    merged = gate(merge(*sets), force=force, what="merged calibration")
    merged.save(out_dir / "calibration.json")
    atomic_write_text(out_dir / "campaign.json", json.dumps({
        "unit": {"serial": truth.serial, "model": truth.model}, "grade": spec.name, "seed": seed,
        "procedures": list(results), "analysis_options": {plan.name(k): a for k, a in sorted(done.options.items())},
        "calibration_id": merged.id, "warnings": {n: r.warnings for n, r in results.items()}}, indent=1) + "\n")
    if store is not None:
        from workbench.procedure import result_json

        def write() -> None:  # one transaction: every session record, result and the merged set, or nothing
            for k, (name, r) in enumerate(results.items()):
                s = done.sessions[k]
                store.add_session(s.id, s.serial, s.model, name, s.path, s.sha256, s.n_steps, True)
                store.add_result(name, s.id, s.serial, json.loads(result_json(r)), None)
            store.add_set(merged)
        store.write_together(write)
    return CampaignResult(merged, results, out_dir, {plan.name(k): u for k, u in done.usage.items()}, done.busy_s)
