"""Kalibr imu.yaml (workbench/exports/kalibr.py): the set's SI noise terms written as Kalibr reads them."""

import numpy as np
import pytest
import yaml

from workbench.calset import CalibrationSet, TriadCalibration, Unit
from workbench.errors import ExportError
from workbench.exports import kalibr
from workbench.model import TriadModel


def _set(noise: dict, notes: dict | None = None) -> CalibrationSet:
    tc = TriadCalibration(TriadModel(bias=[0, 0, 0]), {})
    return CalibrationSet(Unit("SN7", "m"), {"gyro": tc, "accel": tc}, noise=noise, notes=notes or {})


NOISE = {
    "gyro": {"arw": [1e-5, 3e-5, 2e-5], "rrw": [1e-7, 1e-7, 1e-7], "bias_instability": [1e-6] * 3},
    "accel": {"vrw": [4e-4] * 3, "rrw": [None, 2e-6, None], "rrw_ci95": [[0.0, 5e-6], [1e-6, 3e-6], [0.0, 7e-6]]},
}


def test_values_are_the_si_terms_largest_axis():
    out = kalibr.export(_set(NOISE, {"allan": {"sample_rate_hz": 200.0}}))
    doc = yaml.safe_load(out.text)
    assert doc["update_rate"] == 200.0 and doc["rostopic"] == "/imu0"
    # Kalibr's continuous-time densities are the SI terms themselves (rad/s/sqrt(Hz) = ARW N, ...)
    assert doc["gyroscope_noise_density"] == pytest.approx(3e-5, rel=1e-6)
    assert doc["gyroscope_random_walk"] == pytest.approx(1e-7, rel=1e-6)
    assert doc["accelerometer_noise_density"] == pytest.approx(4e-4, rel=1e-6)
    # accel RRW observed on y only: the largest 95 % upper bound (7e-6) is written, conservatively
    assert doc["accelerometer_random_walk"] == pytest.approx(7e-6, rel=1e-6)
    assert any("gyro.arw: per-axis values" in d for d in out.dropped)
    assert any("accel.rrw: not observed on some axis" in d for d in out.dropped)
    assert any("gyro.bias_instability: no Kalibr field" in d for d in out.dropped)
    assert not any("update_rate" in d for d in out.dropped)


def test_default_rate_is_said_and_missing_terms_refused():
    out = kalibr.export(_set(NOISE))
    assert yaml.safe_load(out.text)["update_rate"] == kalibr.DEFAULT_RATE_HZ
    assert any("update_rate: not in the set" in d for d in out.dropped)
    with pytest.raises(ExportError, match="no noise block"):
        kalibr.export(_set({}))
    unbounded = {**NOISE, "accel": {"vrw": [4e-4] * 3, "rrw": [None, None, None]}}
    with pytest.raises(ExportError, match=r"noise.accel.rrw is neither observed nor bounded"):
        kalibr.export(_set(unbounded))
    with pytest.raises(ExportError, match=r"no noise.accel block"):
        kalibr.export(_set({"gyro": NOISE["gyro"]}))


def test_values_round_trip_to_float_precision():
    noise = {"gyro": {"arw": [np.pi * 1e-5] * 3, "rrw": [np.e * 1e-7] * 3}, "accel": {"vrw": [1.2345678e-4] * 3,
                                                                                       "rrw": [9.87654321e-6] * 3}}
    doc = yaml.safe_load(kalibr.export(_set(noise)).text)
    assert doc["gyroscope_noise_density"] == pytest.approx(np.pi * 1e-5, rel=1e-6)  # written with 7 digits
    assert doc["accelerometer_random_walk"] == pytest.approx(9.87654321e-6, rel=1e-6)
