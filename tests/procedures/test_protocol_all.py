"""Every registered procedure follows the procedure and result protocols on a short simulated session.

For each procedure in ``procedures/`` (the registry, so a new one is checked without editing this
file): record its shortest sequence on the simulated rig, analyse it through the plumbing
(``workbench.procedure.run_analysis``), then check the :class:`~workbench.result.AnalysisResult`
protocol on the :class:`~workbench.procedure.ProcedureResult` and that ``result.json`` holds the
summary lines, the analysis options used (every declared analysis option, defaults filled in)
and the software version. Numbers are checked by each procedure's own tests; this checks shape.
"""

from __future__ import annotations

import json

import pytest

from workbench import __version__, registry
from workbench.analysis.northfinding import NorthFinding
from workbench.analysis.thermal import ThermalResult
from workbench.analysis.turntable_fit import TriadFit
from workbench.calset import CalibrationSet
from workbench.grades import draw_unit, load_spec
from tests.nav.conftest import calibration_from_truth
from workbench.jobs import needs_calibration, record_procedure
from workbench.options import declarations
from workbench.procedure import ProcedureResult, run_analysis
from workbench.result import AnalysisResult, CoefficientResult
from workbench.rigconfig import load_rig_config

# the shortest recording each procedure accepts (sequence options), and its grade; ANALYSIS: the
# analysis options a short recording needs (a GPS loss inside the drive)
SHORT: dict[str, tuple[str, dict]] = {
    "ahrs-table": ("industrial_mems", {"mounts": [[10.0, -5.0]], "rates_dps": [20.0, -45.0], "rotate_s": 20.0,
                                       "dwell_s": 5.0}),
    "allan": ("industrial_mems", {"duration_s": 300.0, "soak": False}),
    "carousel": ("cvg_two_axis", {"laps": 1, "rate_deg_s": 30.0}),
    "earth-rate": ("cvg_two_axis", {"dwell_s": 5.0, "step_deg": 90.0, "turns": 1}),
    "ferraris": ("industrial_mems", {"dwell_s": 3.0}),
    "land-ins": ("industrial_mems", {"cruise_s": 20.0, "precalibration": False}),
    "lns-dead-reckoning": ("industrial_mems", {"road": [{"kind": "stop", "duration_s": 20},
                                                        {"kind": "straight", "duration_s": 30, "speed_mps": 10},
                                                        {"kind": "stop", "duration_s": 10}]}),
    "magnetometer": ("industrial_mems", {"yaw_steps": 6, "dwell_s": 1.0}),
    "maytagging": ("cvg_two_axis", {"dwell_s": 5.0, "count": 2}),
    "multiposition": ("industrial_mems", {"dwell_s": 3.0}),
    "rate": ("industrial_mems", {"rates_fs": [0.05, 0.5], "min_duration_s": 2.0}),
    "redundant": ("cvg_two_axis", {"dwell_s": 5.0, "turns": 2}),
    "thermal": ("industrial_mems", {"profile": "ramp", "t_min_c": 20.0, "t_max_c": 30.0, "ramp_c_per_min": 5.0,
                                    "dwell_s": 3.0}),  # a ramp records in a third of a soak's CPU time
    "zupt-alignment": ("industrial_mems", {"dwell_s": 30.0}),
}


ANALYSIS: dict[str, dict] = {"lns-dead-reckoning": {"gps_loss_s": 30.0, "skip_distance_m": 50.0}}


def test_every_registered_procedure_has_a_short_recipe():
    assert set(SHORT) == set(registry.procedures())


@pytest.mark.parametrize("name", sorted(SHORT))
def test_procedure_follows_the_protocols(name, tmp_path):
    proc = registry.procedure(name)
    grade, options = SHORT[name]
    spec = load_spec(grade)
    truth = draw_unit(spec, 3)
    if hasattr(proc, "record_drive"):  # a drive is recorded by the simulated vehicle
        session = proc.record_drive(truth, 3, tmp_path / "session", **options)
    else:
        session = record_procedure(proc, spec, truth, load_rig_config("sim"), 3, None, options)
    given = dict(ANALYSIS.get(name, {}))
    if needs_calibration(proc):
        given["calibration"] = calibration_from_truth(truth)
    res = run_analysis(proc, session, given, tmp_path / "out", None, figures=False)

    assert isinstance(res, ProcedureResult) and isinstance(res, AnalysisResult)
    assert isinstance(res, CoefficientResult)
    lines = res.summary()
    assert lines and all(isinstance(line, str) and line for line in lines)
    assert all(isinstance(w, str) for w in res.warnings)
    json.dumps(res.to_dict())  # JSON-ready
    cal = res.to_calibration(session.unit)
    assert cal is None or isinstance(cal, CalibrationSet)

    stored = json.loads((tmp_path / "out" / "result.json").read_text())
    assert stored["summary"] == lines
    assert stored["software"]["workbench"] == __version__
    declared = {o.name for o in declarations(proc) if o.in_stage("analysis")}
    assert declared <= set(stored["options"]), declared - set(stored["options"])
    assert set(stored["options"]) - {"calibration"} <= declared
    assert stored["warnings"] == list(res.warnings)

    # the estimator's own result object(s) behind the procedure result follow the protocol too
    for obj in _analysis_results(res.payload):
        assert isinstance(obj, AnalysisResult), type(obj).__name__
        own = obj.summary()
        assert own and all(isinstance(line, str) for line in own)
        json.dumps(obj.to_dict())


# estimator result types that follow workbench.result.AnalysisResult (the rest: see docs/architecture.md)
PROTOCOL_TYPES = (TriadFit, ThermalResult, NorthFinding)


def _analysis_results(payload) -> list:
    values = payload.values() if isinstance(payload, dict) else [payload]
    return [v for v in values if isinstance(v, PROTOCOL_TYPES)]


@pytest.mark.parametrize("name", sorted(SHORT))
def test_a_misspelt_option_is_refused_naming_the_declared_one(name):
    from workbench.errors import ProcedureError
    from workbench.options import split

    proc = registry.procedure(name)
    for opt in declarations(proc)[:3]:
        typo = opt.name[:-1] + ("x" if opt.name[-1] != "x" else "y")
        with pytest.raises(ProcedureError, match=rf"{name}: unknown option '{typo}' \(did you mean {opt.name}\?\)"):
            split(proc, {typo: opt.default})
