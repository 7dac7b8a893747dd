"""diff_sets: a change in sigma only where both versions observed a coefficient; "not observed" is a state."""

import numpy as np

from workbench.calset import CalibrationSet, TriadCalibration, Unit
from workbench.diff import CHANGED, NOT_OBSERVED, NOT_OBSERVED_A, NOT_OBSERVED_B, ONLY_B, diff_sets
from workbench.model import TriadModel


def _set(bias, bias_sigma, mag: bool = False) -> CalibrationSet:
    triads = {"gyro": TriadCalibration(TriadModel(bias=bias), {"bias": np.asarray(bias_sigma, float)})}
    if mag:
        triads["mag"] = TriadCalibration(TriadModel(bias=[1.0, 2.0, 3.0]))
    return CalibrationSet(Unit("U1"), triads)


def test_not_observed_is_a_state_never_a_change_in_sigma():
    # x observed in both (2e-6 apart, sigma 1e-6 each: 2e-6 / sqrt(2) / 1e-6 = 1.414 sigma);
    # y estimated in A only (B holds the prior 0); z estimated in B only; the campaign's false alarms
    # were of the y kind: -2700 sigma from an estimate against a prior
    a = _set([1e-5, 2.7e-3, 0.0], [1e-6, 1e-6, np.nan])
    b = _set([1.2e-5, 0.0, 5e-4], [1e-6, np.nan, 1e-6])
    rows = {r.index: r for r in diff_sets(a, b)}
    assert rows[(0,)].state == CHANGED and np.isclose(rows[(0,)].change_in_sigma, 2 / np.sqrt(2))
    assert rows[(1,)].state == NOT_OBSERVED_B and np.isnan(rows[(1,)].change_in_sigma)
    assert rows[(2,)].state == NOT_OBSERVED_A and np.isnan(rows[(2,)].change_in_sigma)
    assert np.isnan(rows[(1,)].sigma) and not rows[(1,)].observed_in_both
    assert [r.state for r in diff_sets(a, b)][0] == CHANGED  # changes come before the not-observed rows


def test_neither_observed_and_triad_only_in_one_set():
    a = _set([1e-5, 0.0, 0.0], [np.nan, np.nan, np.nan])
    b = _set([2e-5, 0.0, 0.0], [np.nan, np.nan, np.nan], mag=True)
    rows = diff_sets(a, b)
    assert [(r.field, r.state) for r in rows] == [("bias", NOT_OBSERVED), ("(triad)", ONLY_B)]
    assert all(np.isnan(r.change_in_sigma) for r in rows)


def test_sets_of_different_models_or_without_a_common_sensor_are_refused():
    import pytest

    from workbench.errors import CalibrationFormatError

    a = CalibrationSet(Unit("U1", "hg1700"), {"gyro": TriadCalibration(TriadModel(bias=[1e-5, 0, 0]))})
    b = CalibrationSet(Unit("U2", "industrial_mems"), {"gyro": TriadCalibration(TriadModel(bias=[2e-5, 0, 0]))})
    with pytest.raises(CalibrationFormatError, match=r"A .* is a 'hg1700' \(U1\), B .* a 'industrial_mems' \(U2\)"):
        diff_sets(a, b)
    mag = CalibrationSet(Unit("U1", "hg1700"), {"mag": TriadCalibration(TriadModel(bias=[1.0, 2.0, 3.0]))})
    with pytest.raises(CalibrationFormatError, match="holds gyro, B .* holds mag: no sensor in common"):
        diff_sets(a, mag)
    same_model = CalibrationSet(Unit("U3", "hg1700"), {"gyro": TriadCalibration(TriadModel(bias=[2e-5, 0, 0]))})
    assert len(diff_sets(a, same_model)) == 1  # two units of one model: compared


def test_thermal_polynomials_about_different_references_are_not_comparable():
    from workbench.diff import NOT_COMPARABLE
    from workbench.model import ThermalModel

    def thermal_set(t_ref, bias_poly):
        poly = np.asarray(bias_poly, float)
        model = TriadModel(bias=[1e-5, 0, 0], thermal=ThermalModel(t_ref, poly, np.zeros((3, 0))))
        return CalibrationSet(Unit("U1", "m"), {"gyro": TriadCalibration(model, {"thermal.bias_poly": np.full(poly.shape, 1e-7)})})

    # about 20 and 25 °C, the same slope: the c0 columns differ by 5 °C x slope, not by a change of the unit
    a, b = thermal_set(20.0, [[0, 1e-6]] * 3), thermal_set(25.0, [[5e-6, 1e-6]] * 3)
    (row,) = [r for r in diff_sets(a, b) if r.field.startswith("thermal.")]
    assert row.state == NOT_COMPARABLE and "A 20 °C, B 25 °C" in row.note and np.isnan(row.change_in_sigma)
    c = thermal_set(20.0, [[0, 1e-6, 1e-8]] * 3)  # a quadratic against a line
    (row,) = [r for r in diff_sets(a, c) if r.field.startswith("thermal.")]
    assert row.state == NOT_COMPARABLE and "different orders (A 1, B 2)" in row.note
    same = [r for r in diff_sets(a, thermal_set(20.0, [[0, 1.2e-6]] * 3)) if r.field.startswith("thermal.")]
    assert {r.state for r in same} == {CHANGED} and len(same) == 3  # one slope per axis, 2e-7 / (1e-7 √2) σ
    assert np.allclose([r.change_in_sigma for r in same], 2e-7 / np.hypot(1e-7, 1e-7))
