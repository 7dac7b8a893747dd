"""The procedure result and its files (workbench/procedure.py: ProcedureResult, result.json, outputs, provenance)."""

import json

import numpy as np
import pytest

from workbench import __version__
from workbench.calset import CalibrationSet, TriadCalibration, Unit
from workbench.errors import ProcedureError
from workbench.jobs import simulate
from workbench.model import TriadModel
from workbench.procedure import ProcedureResult, lab_option, result_json, with_session_provenance, write_outputs
from workbench.sequence import Hold, Sequence
from workbench.units import factor


def _result(unit=Unit("SN1", "m")) -> ProcedureResult:
    cal = CalibrationSet(unit, {"gyro": TriadCalibration(TriadModel(bias=[1e-6, 0, 0]), {"bias": np.full(3, 1e-7)})})
    return ProcedureResult("demo", {"value_si": np.float64(1.5), "array": np.arange(3)}, cal, None,
                           ["demo line"], ["a warning"], {"dwell_s": 5.0})


def test_result_json_holds_summary_options_software_and_the_set_id():
    res = _result()
    doc = json.loads(result_json(res))
    assert doc["procedure"] == "demo" and doc["value_si"] == 1.5 and doc["array"] == [0, 1, 2]
    assert doc["summary"] == ["demo line"] and doc["warnings"] == ["a warning"]
    assert doc["options"] == {"dwell_s": 5.0} and doc["software"] == {"workbench": __version__}
    assert doc["calibration_id"] == res.calibration.id
    assert res.to_dict() == doc
    assert res.summary() == ["demo line"] and res.summary == ["demo line"]


def test_to_calibration_checks_the_unit():
    res = _result()
    assert res.to_calibration(Unit("SN1", "m")) is res.calibration and res.to_calibration() is res.calibration
    with pytest.raises(ProcedureError, match="demo: the calibration is of unit SN1, not SN2"):
        res.to_calibration(Unit("SN2", "m"))
    assert ProcedureResult("none").to_calibration(Unit("SN1")) is None


def test_outputs_written_whole(tmp_path):
    files = write_outputs(_result(), tmp_path / "out")
    assert sorted(p.name for p in files) == ["calibration.json", "result.json"]
    assert CalibrationSet.load(tmp_path / "out" / "calibration.json").unit.serial == "SN1"
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["calibration.json", "result.json"]


def test_session_provenance_and_warnings_reach_the_set():
    session, _ = simulate(Sequence("s", [Hold("z-down", 0.0, 1.0)]), "industrial_mems", seed=1)
    res = with_session_provenance(_result(session.unit), session)
    assert res.calibration.provenance.procedures == ("demo",)
    (prov,) = res.calibration.provenance.sessions
    assert prov["id"] == session.id and len(prov["sha256"]) == 64
    assert res.calibration.notes["demo"]["warnings"] == ["a warning"]
    assert with_session_provenance(ProcedureResult("none"), session).calibration is None


def test_lab_option_converts_a_magnitude_to_si():
    assert lab_option("demo", {}, "gyro_bias_instability_deg_h", "deg/h") is None
    got = lab_option("demo", {"gyro_bias_instability_deg_h": [1.0, 2.0, 3.0]}, "gyro_bias_instability_deg_h", "deg/h")
    np.testing.assert_allclose(got, np.array([1.0, 2.0, 3.0]) * factor("deg/h"))
    with pytest.raises(ProcedureError, match="demo: .*gyro_bias_instability_deg_h"):
        lab_option("demo", {"gyro_bias_instability_deg_h": -1.0}, "gyro_bias_instability_deg_h", "deg/h")
