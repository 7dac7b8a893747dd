"""The canonical exports (workbench/exports/canonical_json.py, canonical_yaml.py) read back to the same set."""

import numpy as np

from workbench.calset import CalibrationSet, TriadCalibration, Unit
from workbench.exports import canonical_json, canonical_yaml
from workbench.model import TriadModel


def _set() -> CalibrationSet:
    tc = TriadCalibration(TriadModel(bias=[1e-3, -2e-3, np.pi * 1e-4], scale_misalignment=np.eye(3) * 1e-4),
                          {"bias": np.array([1e-5, np.nan, 1e-5]), "scale_misalignment": np.full((3, 3), 1e-6)})
    return CalibrationSet(Unit("SN9", "m"), {"gyro": tc}, noise={"gyro": {"arw": [1e-5, None, 2e-5]}})


def test_json_and_yaml_read_back_to_the_same_document():
    cal = _set()
    for module in (canonical_json, canonical_yaml):
        out = module.export(cal)
        assert out.dropped == []
        back = (CalibrationSet.from_json(out.text) if module is canonical_json
                else CalibrationSet.from_yaml(out.text))
        assert back.to_dict() == cal.to_dict(), module.FORMAT
        assert back.sha256() == cal.sha256()
        np.testing.assert_array_equal(back.triads["gyro"].sigma_of("bias"), [1e-5, np.nan, 1e-5])
