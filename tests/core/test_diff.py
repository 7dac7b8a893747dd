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
