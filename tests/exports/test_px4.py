"""PX4 export: the exported parameters, applied with PX4's documented formulas, reproduce our compensation.

The formulas below are written from the PX4 documentation (user guide "Thermal Calibration and
Compensation": offset = X0 + X1 d + X2 d^2 + X3 d^3, d = clamp(T, TMIN, TMAX) - TREF,
corrected = (raw - offset) * scale) and the sensor calibration library (accel
(raw - thermal - CAL_ACC0_xOFF) * CAL_ACC0_xSCALE; gyro raw - thermal - CAL_GYRO0_xOFF; mag
S (raw - CAL_MAG0_xOFF) in gauss, S symmetric from xSCALE and xODIAG = (01, 02, 12)).
"""

from __future__ import annotations


from dataclasses import replace

import numpy as np
import pytest

from workbench.exports import px4
from workbench.model import ThermalModel, TriadModel

from tests.exports._thermal_sets import RANGES, T_RANGE, expressible_set, read_params, true_inputs

# float32 parameters carry 7 significant digits; the bound is 1e-6 of the range
TOL = 1e-6


def px4_thermal(p: dict, letter: str, temp_c: np.ndarray) -> np.ndarray:
    t = np.clip(temp_c, p[f"TC_{letter}0_TMIN"], p[f"TC_{letter}0_TMAX"]) - p[f"TC_{letter}0_TREF"]
    return np.stack([sum(p[f"TC_{letter}0_X{k}_{i}"] * t**k for k in range(4)) for i in range(3)], axis=1)


def test_inertial_corrections_match_our_compensation():
    cal = expressible_set()
    exp = px4.export(cal)
    p = read_params(exp.text, "\t")
    assert p["TC_A_ENABLE"] == 1 and p["TC_G_ENABLE"] == 1
    temps = np.linspace(*T_RANGE, 50)
    for triad, letter, cal_name in (("accel", "A", "CAL_ACC0"), ("gyro", "G", "CAL_GYRO0")):
        model = cal.model(triad)
        x = true_inputs(triad, temps.size, 1)
        raw = model.apply(x, temperature_c=temps)
        off = np.array([p[f"{cal_name}_{a}OFF"] for a in "XYZ"])
        corrected = raw - px4_thermal(p, letter, temps) - off
        if triad == "accel":
            corrected = corrected * np.array([p[f"{cal_name}_{a}SCALE"] for a in "XYZ"])
        ours = model.compensate(raw, temperature_c=temps)
        assert np.abs(corrected - ours).max() < TOL * RANGES[triad], triad
        assert np.abs(ours - x).max() < 1e-9 * RANGES[triad]
    assert exp.dropped == []


def test_magnetometer_in_gauss_matches_our_compensation():
    cal = expressible_set()
    p = read_params(px4.export(cal).text, "\t")
    s = np.array([[p["CAL_MAG0_XSCALE"], p["CAL_MAG0_XODIAG"], p["CAL_MAG0_YODIAG"]],
                  [p["CAL_MAG0_XODIAG"], p["CAL_MAG0_YSCALE"], p["CAL_MAG0_ZODIAG"]],
                  [p["CAL_MAG0_YODIAG"], p["CAL_MAG0_ZODIAG"], p["CAL_MAG0_ZSCALE"]]])
    off_gauss = np.array([p[f"CAL_MAG0_{a}OFF"] for a in "XYZ"])
    x = true_inputs("mag", 40, 2)
    raw_gauss = cal.model("mag").apply(x) / 100.0  # 1 gauss = 100 µT
    corrected_ut = (raw_gauss - off_gauss) @ s.T * 100.0
    assert np.abs(corrected_ut - cal.model("mag").compensate(cal.model("mag").apply(x))).max() < TOL * RANGES["mag"]
    assert abs(off_gauss[0] - 0.10) < 1e-12  # 10 µT hard iron = 0.1 gauss


def test_what_px4_cannot_hold_is_dropped_with_a_reason():
    cal = expressible_set()
    g = cal.model("gyro")
    full = TriadModel(bias=g.bias, scale_misalignment=[[1e-3, 2e-4, 0], [0, -1e-3, 0], [0, 0, 5e-4]],
                      nonlinearity=[1e-4, 0, 0], g_sensitivity=np.full((3, 3), 1e-5),
                      thermal=ThermalModel(25.0, np.column_stack([g.thermal.bias_poly, np.full((3, 2), 1e-11)]),
                                           [[0, 5e-5, 1e-6]] * 3))
    cal2 = replace(cal, triads={**cal.triads, "gyro": replace(cal.triads["gyro"], model=full)})
    dropped = px4.export(cal2).dropped
    text = "\n".join(dropped)
    for phrase in ("gyro: misalignment", "gyro: scale factor", "gyro: quadratic nonlinearity", "gyro: g-sensitivity",
                   "gyro: scale-factor temperature polynomial", "order 5 > 3"):
        assert phrase in text, phrase
    assert all("\n" not in d for d in dropped)


def test_order_five_projected_to_cubic_within_the_reported_deviation():
    cal = expressible_set()
    g = cal.model("gyro")
    poly5 = np.column_stack([g.thermal.bias_poly, np.full((3, 2), [2e-10, -1e-12])])
    model = replace(g, thermal=ThermalModel(25.0, poly5))
    cal2 = replace(cal, triads={**cal.triads, "gyro": replace(cal.triads["gyro"], model=model)})
    exp = px4.export(cal2)
    p = read_params(exp.text, "\t")
    temps = np.linspace(*T_RANGE, 200)
    err = px4_thermal(p, "G", temps) - (model.bias + model.thermal.bias_shift(temps))
    (line,) = [d for d in exp.dropped if "order 5" in d]
    value, unit = line.split("max deviation ")[1].split()[:2]
    assert unit == "°/h)"  # the unit vocabulary's gyro bias unit
    reported = float(value) * np.pi / 180 / 3600  # °/h -> rad/s
    assert np.abs(err).max() <= 1.01 * reported + TOL * RANGES["gyro"]


@pytest.mark.parametrize("t_ref", [25.0, 40.0])
def test_reference_temperature_and_range_written(t_ref):
    cal = expressible_set(t_ref)
    p = read_params(px4.export(cal).text, "\t")
    assert p["TC_G0_TREF"] == t_ref and (p["TC_G0_TMIN"], p["TC_G0_TMAX"]) == T_RANGE
