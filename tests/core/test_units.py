"""The one unit vocabulary: every quantity a set can hold has a lab unit, and the conversions are right."""

import numpy as np
import pytest

from workbench import units
from workbench.calset import NOISE_TERMS, CalibrationSet, TriadCalibration, Unit
from workbench.coefficients import noise_rows, triad_rows
from workbench.model import ThermalModel, TriadModel


def _full_set() -> CalibrationSet:
    th = ThermalModel(23.0, np.ones((3, 3)) * 1e-6, np.ones((3, 2)) * 1e-6)
    tri = {t: TriadCalibration(TriadModel(bias=[1e-3] * 3, nonlinearity=[1e-6] * 3, thermal=th,
                                          g_sensitivity=np.eye(3) * 1e-5 if t == "gyro" else None),
                               field_norm_ut=48.0 if t == "mag" else None) for t in ("gyro", "accel", "mag")}
    noise = {t: {term: [1e-5] * 3 for term in terms} for t, terms in NOISE_TERMS.items()}
    return CalibrationSet(Unit("U"), tri, noise=noise)


def test_every_displayed_quantity_has_a_vocabulary_entry():
    """Every coefficient and noise term of a full set is shown in a unit of the vocabulary, never in SI words."""
    cal = _full_set()
    rows = [r for t in cal.triads for r in triad_rows(cal, t)]
    assert {r.field for r in rows} >= {"bias", "scale_misalignment", "nonlinearity", "g_sensitivity",
                                       "thermal.bias_poly", "thermal.scale_poly", "field_norm"}
    shown = {r.unit for r in rows} | {r.unit for r in noise_rows(cal)}
    for bad in ("deg/h", "uT", "1/SI", "rad/s", "m/s^2", "m/s³", "m/s"):
        assert bad not in shown
    for triad, terms in NOISE_TERMS.items():
        for term in terms:
            assert units.unit_of(triad, term)
    with pytest.raises(KeyError, match="no entry for gyro wobble"):
        units.unit_of("gyro", "wobble")


@pytest.mark.parametrize("triad,quantity,si,expected", [
    ("gyro", "bias", np.pi / 180 / 3600, 1.0),  # 1 °/h
    ("accel", "bias", 9.80665e-3, 1.0),  # 1 mg
    ("gyro", "misalignment", 1e-3, 1.0),  # 1 mrad
    ("gyro", "scale_factor", 1e-6, 1.0),  # 1 ppm
    # measured = w + k w^2: k = 1e-6 / (rad/s) is a scale error of 1e-6 per rad/s = 1e-6 * (pi/180) per °/s
    ("gyro", "nonlinearity", 1e-6, 1e-6 * 1e6 * np.pi / 180),
    # k w^2 at w = 1 g (9.80665 m/s^2): k 9.80665^2 m/s^2 = k * 9.80665^2 / 9.80665e-6 µg
    ("accel", "nonlinearity", 1e-6, 1e-6 * 9.80665 / 1e-6),
    ("gyro", "g_sensitivity", np.pi / 180 / 3600 / 9.80665, 1.0),  # 1 °/h per g
    ("gyro", "arw", np.pi / 180 / 60, 1.0),  # 1 °/√h = (pi/180) rad / 60 √s
    ("accel", "vrw", 9.80665e-6, 1.0),  # 1 µg/√Hz
    ("gyro", "rrw", np.pi / 180 / 3600 / 60, 1.0),  # 1 °/h/√h
    ("accel", "rate_ramp", 9.80665e-6 / 3600, 1.0),  # 1 µg/h
])
def test_conversions_by_hand(triad, quantity, si, expected):
    assert units.to_unit(si, units.unit_of(triad, quantity)) == pytest.approx(expected, rel=1e-12)


def test_one_unit_per_figure_and_thermal_labels():
    assert units.show("gyro", "misalignment", 0.386e-3, 0.0493e-3) == "0.386 ± 0.049 mrad"
    assert units.show("gyro", "bias", 1e-5, np.nan).endswith("(σ not observed) °/h")
    assert units.thermal_label("gyro", "bias_poly", 2) == "°/h/°C²"
    assert units.thermal_label("accel", "scale_poly", 1) == "ppm/°C"


def test_si_unit_of_each_lab_unit():
    from workbench.units import factor, si_unit, units_of

    assert si_unit("deg/h") == "rad/s" and si_unit("gauss") == "uT" and si_unit("mg") == "m/s^2"
    assert si_unit("deg/sqrt(h)") is None  # a noise density: outside the table
    for si in ("rad/s", "rad", "m/s^2", "uT", "m/s", "m", "degC"):
        assert si in units_of(si) and factor(si) == 1.0  # the SI unit itself has factor 1
        assert all(si_unit(u) == si for u in units_of(si))
    import pytest

    with pytest.raises(ValueError, match="unknown unit 'furlong'"):
        si_unit("furlong")


def test_value_and_sigma_share_one_unit():
    # the magnetometer is in µT inside: -2.22 µT ± 0.005 µT reads with the unit written once
    assert units.pm(-2.22, 0.005, "uT", 3) == "-2.22 ± 0.005 µT"
    assert units.pm(units.from_unit(8.0, "deg/h"), float("nan"), "deg/h") == "8 (σ not observed) °/h"
    assert units.pm(float("nan"), 1.0, "uT") == "not observed" and units.pm(1.5, None, "uT") == "1.5 µT"
