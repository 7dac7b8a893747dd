"""Display rows of a calibration set (workbench/coefficients.py): every coefficient in its lab unit.

Values are exact lab-unit numbers converted to SI here, so the rows must give them back to
floating-point rounding (rel 1e-12)."""

import numpy as np
import pytest

from workbench import coefficients as co
from workbench.calset import CalibrationSet, TriadCalibration, Unit
from workbench.model import ThermalModel, TriadModel
from workbench.units import factor

DEG_H, MRAD, PPM = factor("deg/h"), 1e-3, 1e-6


def _set() -> CalibrationSet:
    m = np.diag([100.0, -50.0, 20.0]) * PPM
    m[0, 2] = 0.2 * MRAD
    gyro = TriadCalibration(
        TriadModel(bias=np.array([1.0, -2.0, 0.5]) * DEG_H, scale_misalignment=m,
                   thermal=ThermalModel(25.0, np.column_stack([np.zeros(3), np.full(3, 0.01 * DEG_H)]),
                                        np.zeros((3, 0)))),
        {"bias": np.array([0.1, 0.1, np.nan]) * DEG_H, "scale_misalignment": np.full((3, 3), 5 * PPM),
         "thermal.bias_poly": np.column_stack([np.zeros(3), np.full(3, 0.001 * DEG_H)])},
        thermal_range_c=(5.0, 45.0))
    mag = TriadCalibration(TriadModel(bias=[1.0, 2.0, 3.0]), {"bias": np.full(3, 0.1)},
                           field_norm_ut=48.5, field_norm_ut_sigma=0.2)
    noise = {"gyro": {"arw": [np.radians(0.2) / 60] * 3, "arw_ci95": [[np.radians(0.18) / 60, np.radians(0.22) / 60]] * 3}}
    return CalibrationSet(Unit("SN1", "m"), {"gyro": gyro, "mag": mag}, noise=noise)


def test_gyro_rows_in_lab_units():
    rows = {r.name: r for r in co.triad_rows(_set(), "gyro")}
    assert rows["bias x"].value == pytest.approx(1.0, rel=1e-12) and rows["bias x"].unit == "°/h"
    assert rows["bias x"].sigma == pytest.approx(0.1, rel=1e-12) and rows["bias x"].observed
    assert not rows["bias z"].observed and np.isnan(rows["bias z"].sigma)
    assert rows["scale factor y"].value == pytest.approx(-50.0, rel=1e-12) and rows["scale factor y"].unit == "ppm"
    assert rows["misalignment M[x,z]"].value == pytest.approx(0.2, rel=1e-12)
    assert rows["misalignment M[x,z]"].unit == "mrad" and rows["misalignment M[x,z]"].quantity == "misalignment"
    # thermal: c0 held at zero is not listed, c1 per °C
    assert "bias thermal c0 x" not in rows
    c1 = rows["bias thermal c1 x"]
    assert c1.value == pytest.approx(0.01, rel=1e-12) and c1.sigma == pytest.approx(0.001, rel=1e-12)
    assert c1.unit == "°/h/°C"
    assert "nonlinearity x" not in rows  # zero and without sigma: not shown


def test_mag_field_norm_and_thermal_reference():
    rows = {r.name: r for r in co.triad_rows(_set(), "mag")}
    assert rows["field norm"].value == pytest.approx(48.5) and rows["field norm"].unit == "µT"
    assert rows["field norm"].sigma == pytest.approx(0.2)
    text = co.thermal_reference(_set(), "gyro")
    assert "t_ref 25 °C" in text and "valid 5.0 .. 45.0 °C" in text
    assert co.thermal_reference(_set(), "mag") is None


def test_noise_rows_with_their_intervals():
    rows = co.noise_rows(_set())
    assert [(r.triad, r.term, r.axis) for r in rows] == [("gyro", "arw", a) for a in "xyz"]
    assert rows[0].value == pytest.approx(0.2, rel=1e-12) and rows[0].unit == "°/√h"
    assert rows[0].ci95 == pytest.approx((0.18, 0.22), rel=1e-12)


def test_texts():
    assert co.value_text(np.nan) == "—" and co.value_text(1.234567) == "1.2346"
    assert co.sigma_text(np.nan) == "not observed" and co.sigma_text(0.1, k=2) == "0.20"  # two significant digits of the k = 2 uncertainty
    assert co.ci_text(None) == "" and co.ci_text((0.18, 0.22)) == "0.18 .. 0.22"
    assert co.element_name("g_sensitivity", (0, 2)) == "g-sensitivity G[x,z]"
    label, f = co.element_unit("accel", "bias", (1,))
    assert label == "mg" and f == pytest.approx(factor("mg"))
