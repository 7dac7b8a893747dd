"""ArduPilot export: the .parm, applied with ArduPilot's documented formulas, reproduces our compensation.

Formulas written from ArduPilot's parameter documentation and IMU/compass correction code
(AP_InertialSensor_tempcal.cpp, AP_InertialSensor_Backend.cpp, AP_Compass_Backend.cpp):
P(d) = (c1 d + c2 d^2 + c3 d^3) * 1e-6 with d = clamp(T, TMIN, TMAX) - 35 °C;
v = raw - P(d(T)) + P(d(T_cal)); accel (v - INS_ACCOFFS) * INS_ACCSCAL, gyro v - INS_GYROFFS;
compass D (raw_mG + COMPASS_OFS) with D symmetric (DIA on the diagonal, ODI = 01, 02, 12).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tests.exports._thermal_sets import RANGES, T_RANGE, expressible_set, read_params, true_inputs
from workbench.exports import ardupilot
from workbench.model import TriadModel

TOL = 1e-6  # of the full scale (issue bound); float32 parameters carry 7 digits


def ap_poly(p: dict, key: str, temp_c: np.ndarray) -> np.ndarray:
    d = np.clip(temp_c, p["INS_TCAL1_TMIN"], p["INS_TCAL1_TMAX"]) - 35.0
    return np.stack([sum(p[f"INS_TCAL1_{key}{k}_{a}"] * d**k for k in (1, 2, 3)) * 1e-6 for a in "XYZ"], axis=1)


@pytest.mark.parametrize("t_ref", [25.0, 35.0, 60.0])
def test_inertial_corrections_match_our_compensation(t_ref):
    cal = expressible_set(t_ref)
    exp = ardupilot.export(cal)
    p = read_params(exp.text, ",")
    assert p["INS_TCAL1_ENABLE"] == 1 and (p["INS_TCAL1_TMIN"], p["INS_TCAL1_TMAX"]) == T_RANGE
    temps = np.linspace(*T_RANGE, 50)
    for triad, key, offs, caltemp in (("accel", "ACC", "INS_ACCOFFS", "INS_ACC1_CALTEMP"),
                                      ("gyro", "GYR", "INS_GYROFFS", "INS_GYR1_CALTEMP")):
        model = cal.model(triad)
        x = true_inputs(triad, temps.size, 3)
        raw = model.apply(x, temperature_c=temps)
        v = raw - ap_poly(p, key, temps) + ap_poly(p, key, np.full(temps.size, p[caltemp]))
        v = v - np.array([p[f"{offs}_{a}"] for a in "XYZ"])
        if triad == "accel":
            v = v * np.array([p[f"INS_ACCSCAL_{a}"] for a in "XYZ"])
        assert np.abs(v - model.compensate(raw, temperature_c=temps)).max() < TOL * RANGES[triad], triad
    assert exp.dropped == []


def test_compass_offsets_added_in_milligauss():
    cal = expressible_set()
    p = read_params(ardupilot.export(cal).text, ",")
    d = np.array([[p["COMPASS_DIA_X"], p["COMPASS_ODI_X"], p["COMPASS_ODI_Y"]],
                  [p["COMPASS_ODI_X"], p["COMPASS_DIA_Y"], p["COMPASS_ODI_Z"]],
                  [p["COMPASS_ODI_Y"], p["COMPASS_ODI_Z"], p["COMPASS_DIA_Z"]]])
    ofs = np.array([p[f"COMPASS_OFS_{a}"] for a in "XYZ"])
    assert ofs[0] == pytest.approx(-100.0)  # +10 µT hard iron -> -100 mG (the offset is added)
    x = true_inputs("mag", 40, 4)
    raw_mg = cal.model("mag").apply(x) * 10.0  # 1 µT = 10 mG
    corrected_ut = (raw_mg + ofs) @ d.T / 10.0
    assert np.abs(corrected_ut - x).max() < TOL * RANGES["mag"]


def test_unsymmetric_soft_iron_rotation_is_dropped():
    cal = expressible_set()
    m = cal.model("mag")
    rot = np.array([[0.0, -0.01, 0.0], [0.01, 0.0, 0.0], [0.0, 0.0, 0.0]])  # ~0.57° about z
    skew = replace(m, scale_misalignment=m.scale_misalignment + rot)
    cal2 = replace(cal, triads={**cal.triads, "mag": replace(cal.triads["mag"], model=skew)})
    dropped = ardupilot.export(cal2).dropped
    assert any(d.startswith("mag: rotation part of the soft-iron correction") for d in dropped)


def test_gyro_scale_and_misalignment_are_dropped():
    cal = expressible_set()
    g = cal.model("gyro")
    model = TriadModel(bias=g.bias, scale_misalignment=[[1e-3, 1e-4, 0], [0, 0, 0], [0, 0, 0]], thermal=g.thermal)
    cal2 = replace(cal, triads={**cal.triads, "gyro": replace(cal.triads["gyro"], model=model)})
    text = "\n".join(ardupilot.export(cal2).dropped)
    assert "gyro: misalignment" in text and "gyro: scale factor" in text


def test_shift_polynomial_is_exact():
    c = np.array([[1.0, 2.0, 3.0, 4.0]] * 3)
    z = np.linspace(-5, 5, 11)
    shifted = ardupilot.shift_polynomial(c, 10.0)
    assert np.allclose(np.polyval(shifted[0][::-1], z), np.polyval(c[0][::-1], z + 10.0))
