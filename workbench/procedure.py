"""Procedure results and the analysis plumbing shared by ``run``, ``analyze``, batch and dashboard.

A procedure's ``analyze(session, **options)`` is pure and returns a :class:`ProcedureResult`.
:func:`finish_analysis` then adds provenance to its calibration set, writes the output files
(``result.json``, ``calibration.json``, ``figures/*.png``) and stores the set and result,
all or nothing.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from workbench.calset import CalibrationSet, atomic_write_text
from workbench.files import make_folder
from workbench.json_values import json_default
from workbench.result import SummaryLines
from workbench.session import Session


def lab_option(procedure: str, options: Mapping, key: str, unit: str) -> np.ndarray | None:
    """Option ``key``, a magnitude given in the lab ``unit`` (a number >= 0 or one per axis), in SI; None if absent.

    For a procedure without declared options; a declared ``magnitude`` option is read with
    ``Options.si`` (:mod:`workbench.options`), through the same check.
    """
    from workbench.options import Option, check_options

    if options.get(key) is None:
        return None
    opt = Option(key, "analysis", "magnitude", None, "", unit=unit)
    return check_options(procedure, (opt,), {key: options[key]}).si(key)


@dataclass
class ProcedureResult:
    """What an analysis returns; satisfies :class:`workbench.result.CoefficientResult`.

    ``result`` is the JSON-ready dict written to ``result.json`` (SI unless a key names its
    unit, e.g. ``azimuth_deg``); ``calibration`` the partial calibration set this procedure
    produces (None when its product is not a calibration set); ``payload`` the estimator
    result objects the figures are drawn from; ``summary`` lines for people, in lab units
    (a :class:`~workbench.result.SummaryLines`: ``r.summary`` and ``r.summary()`` agree);
    ``options`` the analysis options used (set by :func:`run_analysis`, JSON-ready, lab units
    as declared).
    """

    procedure: str
    result: dict = field(default_factory=dict)
    calibration: CalibrationSet | None = None
    payload: Any = None
    summary: SummaryLines = field(default_factory=SummaryLines)
    warnings: list[str] = field(default_factory=list)
    options: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.summary, SummaryLines):
            self.summary = SummaryLines(self.summary)

    def to_dict(self) -> dict:
        """The ``result.json`` document (see :func:`result_json`)."""
        return json.loads(result_json(self))

    def to_calibration(self, unit=None) -> CalibrationSet | None:
        """The calibration set (None when the product is not one); ``unit`` must match its unit if given."""
        from workbench.errors import ProcedureError

        cal = self.calibration
        if cal is not None and unit is not None and (unit.serial, unit.model) != (cal.unit.serial, cal.unit.model):
            raise ProcedureError(f"{self.procedure}: the calibration is of unit {cal.unit.serial}, not {unit.serial}")
        return cal


def session_provenance(session: Session) -> dict:
    """Provenance record of one session: id, procedure, SHA-256 of its samples file, rig."""
    sha = session.samples_sha256()
    if sha is None:
        import hashlib

        sha = hashlib.sha256(session.samples.to_csv(index=False).encode()).hexdigest()
    return {"id": session.id, "procedure": session.procedure, "sha256": sha, "rig": session.rig}


def with_session_provenance(result: ProcedureResult, session: Session) -> ProcedureResult:
    """The result with the session's provenance added to its calibration set."""
    if result.calibration is None:
        return result
    cal = result.calibration.with_provenance([result.procedure], [session_provenance(session)])
    if result.warnings:
        notes = dict(cal.notes)
        notes.setdefault(result.procedure, {})
        notes[result.procedure] = {**dict(notes[result.procedure]), "warnings": list(result.warnings)}
        cal = replace(cal, notes=notes)
    return replace(result, calibration=cal)


def result_json(result: ProcedureResult) -> str:
    """``result.json`` text: procedure, result dict, summary lines, warnings, the analysis options used,
    the software version and the calibration id, so that anything downstream (dashboard, certificate)
    shows the stored result without analysing again."""
    from workbench import __version__

    doc: Mapping = {
        "procedure": result.procedure,
        **result.result,
        "summary": list(result.summary),
        "warnings": list(result.warnings),
        "options": dict(result.options),
        "software": {"workbench": __version__},
        "calibration_id": result.calibration.id if result.calibration is not None else None,
    }
    return json.dumps(doc, indent=2, default=json_default) + "\n"


def write_outputs(result: ProcedureResult, out_dir: Path, figures: Mapping | None = None) -> list[Path]:
    """Write ``result.json``, ``calibration.json`` and ``figures/<name>.png`` into ``out_dir``; a folder
    that cannot be made (a file there, a read-only disk) is a WorkbenchError naming it."""
    make_folder(out_dir)
    written = [atomic_write_text(out_dir / "result.json", result_json(result))]
    if result.calibration is not None:
        written.append(result.calibration.save(out_dir / "calibration.json"))
    if figures:
        from workbench.plots.pool import save_figures

        written += save_figures(figures, out_dir / "figures")
    return written


def analysed(proc, session: Session, options: Mapping | None = None, force: bool = False) -> ProcedureResult:
    """``proc.analyze(session, **options)`` with provenance and the options used, through the plausibility gate.

    The one way from an analysis to something that may be stored (``run``, ``analyze``, the
    campaign, batch, the dashboard's runs): an implausible calibration raises
    :class:`workbench.plausibility.ImplausibleCalibration` (one line: quantity, value, limit),
    or with ``force`` carries the failed checks in its notes (:mod:`workbench.plausibility`).
    """
    from workbench.plausibility import gate

    result = with_session_provenance(proc.analyze(session, **dict(options or {})), session)
    result = replace(result, options=used_options(proc, options))
    if result.calibration is not None:
        cal = gate(result.calibration, session, result.result, force, what=f"{result.procedure} calibration")
        result = replace(result, calibration=cal)
    return result


def run_analysis(proc, session: Session, options: Mapping | None = None, out_dir: Path | None = None,
                 store=None, figures: bool = True, force: bool = False) -> ProcedureResult:
    """Analyse ``session`` with procedure module ``proc``; write outputs and store, all or nothing.

    Files go to ``out_dir`` (each written atomically) only after the analysis succeeded and its
    calibration passed the plausibility gate (:func:`analysed`; ``force`` stores an implausible
    one with the failed checks in its notes); the store receives the session record, the result
    and its calibration set last, so a failed analysis leaves both untouched. ``figures=False``
    writes no figures (batch work: they can be drawn later from ``result.json``'s result).
    """
    result = analysed(proc, session, options, force)
    doc = json.loads(result_json(result))
    if out_dir is not None:
        figs = proc.figures(result) if figures and hasattr(proc, "figures") else None
        write_outputs(result, Path(out_dir), figs)
        if figs:  # the store names where they are, for the dashboard and the certificate
            doc["figures_dir"] = str((Path(out_dir) / "figures").resolve())
    if store is not None:
        def write() -> None:  # one transaction: the session record, the result and its set, or nothing
            store.add_session(session.id, session.unit.serial, session.unit.model, result.procedure,
                              str(session.path or ""), session.samples_sha256() or "", len(session.steps), True)
            store.add_result(result.procedure, session.id, session.unit.serial, doc, result.calibration)
        store.write_together(write)
    return result


def used_options(proc, options: Mapping | None) -> dict:
    """The analysis options of an analysis, defaults filled in, JSON-ready (a calibration set by its id)."""
    from workbench.options import validate

    given = dict(options or {})
    cal = given.pop("calibration", None)
    used = dict(validate(proc, given, "analysis"))
    if cal is not None:
        used["calibration"] = getattr(cal, "id", str(cal))
    return used


def procedure_options(name: str, options: Mapping, defaults: Mapping, keys: tuple[str, ...] | None = None) -> dict:
    """A procedure's options (``keys`` of them, default all) with its defaults filled in.

    For a procedure that has not declared ``OPTIONS`` yet: each key of ``defaults`` is taken as
    an option of any type; the check is :func:`workbench.options.check_options` (an unknown
    name raises ProcedureError naming the nearest known one).
    """
    from workbench.options import Option, check_options

    o = check_options(name, [Option(k, "both", "any", v, "") for k, v in defaults.items()], options)
    return {k: o[k] for k in (keys if keys is not None else defaults)}
