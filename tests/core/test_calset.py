import json

import numpy as np
import pytest

from workbench.calset import CalibrationSet, TriadCalibration, Unit, merge
from workbench.errors import CalibrationFormatError
from workbench.model import ThermalModel, TriadModel


def make_set(serial="U1", **kw) -> CalibrationSet:
    accel = TriadCalibration(
        TriadModel(bias=[0.01, -0.02, 0.03], scale_misalignment=np.eye(3) * 1e-3,
                   thermal=ThermalModel(25.0, np.zeros((3, 2)), np.zeros((3, 1)))),
        {"bias": np.array([1e-4, 1e-4, np.nan]), "scale_misalignment": np.full((3, 3), 1e-5)})
    return CalibrationSet(Unit(serial, "industrial_mems"), {"accel": accel}, **kw)


def test_json_round_trip_keeps_values_and_not_observed(tmp_path):
    s = make_set(noise={"gyro": {"arw": [1e-4, None, 1e-4], "arw_ci95": [[9e-5, 1.1e-4], None, [9e-5, 1.1e-4]]}})
    path = s.save(tmp_path / "c.json")
    back = CalibrationSet.load(path)
    assert back.id == s.id and back.created == s.created
    assert np.array_equal(back.model("accel").bias, s.model("accel").bias)
    assert np.isnan(back.triads["accel"].sigma_of("bias")[2])  # null = not observed
    assert np.isnan(back.noise_term("gyro", "arw")[1])
    assert json.loads(path.read_text())["format"] == "workbench-calibration/1"


def _bad(tmp_path, mutate):
    d = make_set().to_dict()
    mutate(d)
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(d))
    return p


@pytest.mark.parametrize("mutate,match", [
    (lambda d: d["accel"].__setitem__("bias", [1, 2]), "accel.bias"),
    (lambda d: d["accel"].__setitem__("scale_misalignment", [[1, 0], [0, 1]]), "accel.scale_misalignment"),
    (lambda d: d["accel"]["scale_misalignment"].__setitem__(0, [float("nan"), 0, 0]), "NaN"),
    (lambda d: d["accel"].__setitem__("scale_misalignment", [[-1, 0, 0], [0, 0, 0], [0, 0, 0]]), "singular"),
    (lambda d: d.__setitem__("gyros", d.pop("accel")), "unknown triad 'gyros'"),
    (lambda d: d.__setitem__("format", "workbench-calibration/2"), "not supported"),
    (lambda d: d.__setitem__("format", "workbench-calibration/0"), "not supported"),
    (lambda d: d.pop("unit"), "unit"),
    # a serial, id or model goes verbatim into exports: a line break would add a line to a parameter file,
    # '*/' a #define to a C header
    (lambda d: d["unit"].__setitem__("serial", "x */\n#define WB_ACCEL_BIAS_X 99.0\n/*"), "unit.serial 'x \\*/"),
    (lambda d: d["unit"].__setitem__("serial", "../../x"), "unit.serial '../../x': use 1-64 letters, digits"),
    (lambda d: d.__setitem__("id", "a\nCAL_ACC0_XOFF 5"), "id 'a.*CAL_ACC0_XOFF 5': use 1-64 letters"),
    (lambda d: d["unit"].__setitem__("model", "m\nINS_ACCOFFS_X 5.0"), "unit.model .*: expected one line"),
])
def test_bad_files_get_one_line_errors_naming_file_and_field(tmp_path, mutate, match):
    p = _bad(tmp_path, mutate)
    with pytest.raises(CalibrationFormatError, match=match) as exc:
        CalibrationSet.load(p)
    assert str(p) in str(exc.value) and "\n" not in str(exc.value)


def test_malformed_json(tmp_path):
    p = tmp_path / "x.json"
    p.write_text("{not json")
    with pytest.raises(CalibrationFormatError, match="not valid JSON"):
        CalibrationSet.load(p)
    p.write_bytes(b"\xff\xfe{")  # was a UnicodeDecodeError traceback
    with pytest.raises(CalibrationFormatError, match="x.json: not UTF-8 text"):
        CalibrationSet.load(p)


def test_merge_takes_observed_elements_and_records_both_provenances():
    a = make_set()
    gyro = TriadCalibration(TriadModel(bias=[1e-3, 2e-3, 3e-3]), {"bias": np.full(3, 1e-5)})
    b = CalibrationSet(Unit("U1", ""), {"gyro": gyro, "accel": TriadCalibration(
        TriadModel(bias=[9, 9, 9]), {"bias": np.array([np.nan, np.nan, 1e-3])})})
    a = a.with_provenance(["multiposition"], [{"id": "s1", "procedure": "multiposition", "sha256": "0" * 64}])
    b = b.with_provenance(["allan"], [{"id": "s2", "procedure": "allan", "sha256": "1" * 64}])
    m = merge(a, b)
    assert set(m.triads) == {"accel", "gyro"}
    # x, y of accel bias observed only in a; z observed only in b
    assert np.allclose(m.model("accel").bias, [0.01, -0.02, 9])
    assert m.provenance.procedures == ("multiposition", "allan")
    assert {s["id"] for s in m.provenance.sessions} == {"s1", "s2"}
    assert m.provenance.merged_from == (a.id, b.id)
    with pytest.raises(CalibrationFormatError, match="different units"):
        merge(a, make_set("U2"))
    # both observe accel bias x: the better-determined estimate wins whatever the order
    worse = CalibrationSet(Unit("U1", ""), {"accel": TriadCalibration(
        TriadModel(bias=[5, 5, 5]), {"bias": np.array([1e-2, np.nan, np.nan])})})
    assert merge(a, worse).model("accel").bias[0] == 0.01 and merge(worse, a).model("accel").bias[0] == 0.01
