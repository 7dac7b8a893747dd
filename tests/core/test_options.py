"""Declared procedure options: one validator for every command (workbench.options)."""

import json

import numpy as np
import pytest

from procedures import maytagging, multiposition, thermal
from workbench.cli import main
from workbench.errors import ProcedureError
from workbench.options import Option, check_options, option_rows, split, validate
from workbench.registry import procedures


def test_every_procedure_declares_each_option_once_with_its_default():
    for name, proc in procedures().items():
        names = [o.name for o in proc.OPTIONS]
        assert len(names) == len(set(names)), name
        assert proc.DEFAULTS == {o.name: o.default for o in proc.OPTIONS}, name
        for o in proc.OPTIONS:  # the declared default passes the declared check
            assert o.check(o.default, name) == o.default, (name, o.name)


def test_unknown_option_names_the_nearest():
    with pytest.raises(ProcedureError, match=r"maytagging: unknown option 'dwel_s' \(did you mean dwell_s\?\)"):
        validate(maytagging, {"dwel_s": 5})
    with pytest.raises(ProcedureError, match="known: "):
        validate(maytagging, {"zzz": 5})


@pytest.mark.parametrize("opts,match", [
    ({"dwell_s": -5}, r"dwell_s=-5 \(s\) must be > 0 s"),
    ({"dwell_s": "long"}, r"dwell_s='long' \(s\) is not a number"),
    ({"count": 2.5}, "count=2.5 is not a whole number"),
    ({"ordering": "AABB"}, "ordering='AABB' is not one of ABAB, ABBA"),
    ({"drift": "yes"}, "drift='yes' is not true or false"),
])
def test_bad_values_are_one_line_procedure_errors(opts, match):
    with pytest.raises(ProcedureError, match=match):
        maytagging.sequence(None, **opts) if "drift" not in opts else validate(maytagging, opts)


def test_split_by_stage_and_si_conversion():
    seq, ana = split(multiposition, {"dwell_s": 5, "earth_rate": "ignore", "table_angle_deg": 90})
    assert seq == {"dwell_s": 5.0, "table_angle_deg": 90.0} and ana == {"earth_rate": "ignore"}
    o = check_options("multiposition", multiposition.OPTIONS, {"table_angle_deg": 90, "position_sigma_deg": 0.01,
                                                                 "gyro_bias_instability_deg_h": [1, 2, 3]}, "sequence")
    assert set(o) == {"positions", "dwell_s", "table_angle_deg"} and o.given == {"table_angle_deg"}
    assert o.si("table_angle_deg") == pytest.approx(np.pi / 2)
    a = validate(multiposition, {"gyro_bias_instability_deg_h": [1, 2, 3], "position_sigma_deg": "auto"}, "analysis")
    assert a.si("gyro_bias_instability_deg_h") == pytest.approx(np.radians([1, 2, 3]) / 3600)
    assert a.si("position_sigma_deg") == "auto" and a.si("accel_bias_instability_mg") is None
    # both-stage options go to both
    seq, ana = split(thermal, {"settle_window_s": 60})
    assert seq == ana == {"settle_window_s": 60.0}


def test_magnitude_type():
    opt = Option("b", "analysis", "magnitude", None, "", unit="mg")
    assert opt.check(2, "p") == 2.0 and opt.check([1, 2, 3], "p") == [1.0, 2.0, 3.0]
    for bad in ("x", [1, 2], -1.0, float("nan")):
        with pytest.raises(ProcedureError, match=r"p: b=.* \(mg\) is not a number >= 0 or a list of 3"):
            opt.check(bad, "p")


def test_option_table_rows():
    rows = {r["name"]: r for r in option_rows(maytagging)}
    assert rows["dwell_s"] == {"name": "dwell_s", "stage": "sequence", "type": "float", "unit": "s",
                               "default": "60.0", "allowed": "> 0 s", "help": "hold per position"}
    assert rows["settle_s"]["stage"] == "both" and rows["drift"]["allowed"] == "null"


@pytest.fixture
def db(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{tmp_path}/w.db")


@pytest.mark.parametrize("args", [
    ["run", "maytagging", "-o", "dwel_s=5", "--dry-run"],
    ["run", "campaign", "-o", "multiposition.dwel_s=5", "--dry-run"],
    ["run", "campaign", "-o", "dwell_s=5", "--dry-run"],
    ["analyze", "maytagging", "/no/such/session", "-o", "dwel_s=5"],
    ["batch", "maytagging", "/no/such/session", "--scheduler", "serial", "-o", "dwel_s=5"],
])
def test_every_command_refuses_a_misspelt_option_with_exit_2(db, capsys, args):
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "unknown option 'dwel_s'" in err or "must name its procedure" in err


def test_procedures_proc_prints_the_option_table(capsys):
    assert main(["procedures", "maytagging"]) == 0
    out = capsys.readouterr().out
    assert "dwell_s" in out and "ABBA" in out and "index_tol_deg" in out


def test_run_passes_analysis_options_to_the_analysis(db, tmp_path, capsys):
    """The bug: ``run -o earth_rate=ignore`` recorded and analysed with the default (Earth rate modelled)."""
    out = tmp_path / "mp"
    assert main(["run", "multiposition", "--seed", "4", "--out", str(out), "--no-store", "-o", "dwell_s=2",
                 "-o", "earth_rate=ignore"]) == 0
    text = capsys.readouterr().out
    assert "Earth rate: not modelled" in text and "Earth rate: modelled" not in text
    result = json.loads((out / "result.json").read_text())
    assert "not modelled" in result["gyro"]["notes"]["earth_rate"]
    assert json.loads((out / "session" / "session.json").read_text())["analysis_options"] == {"earth_rate": "ignore"}


def test_result_protocol_and_stored_result(tmp_path):
    """ProcedureResult satisfies the result protocol; result.json holds summary, options used and version."""
    import workbench
    from workbench.grades import load_spec
    from workbench.procedure import run_analysis
    from workbench.result import AnalysisResult, CoefficientResult
    from workbench.jobs import simulate

    spec = load_spec("industrial_mems")
    session, _ = simulate(multiposition.sequence(spec, dwell_s=2.0), spec, seed=3)
    res = run_analysis(multiposition, session, {"earth_rate": "ignore"}, tmp_path)
    assert isinstance(res, AnalysisResult) and isinstance(res, CoefficientResult)
    assert res.summary() == list(res.summary) and res.summary and res.to_calibration(session.unit) is res.calibration
    doc = json.loads((tmp_path / "result.json").read_text())
    assert doc == res.to_dict()
    assert doc["summary"] == list(res.summary) and doc["software"] == {"workbench": workbench.__version__}
    assert doc["options"] == {o.name: o.default for o in multiposition.OPTIONS if o.stage == "analysis"} | {
        "earth_rate": "ignore"}
