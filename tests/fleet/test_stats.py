"""Fleet statistics (workbench/fleet/stats.py): per-coefficient spread across units, robust outliers."""

import numpy as np
import pytest

from workbench.calset import CalibrationSet, TriadCalibration, Unit
from workbench.fleet.stats import OUTLIER_Z, coefficient_stats
from workbench.model import TriadModel


def _unit(serial: str, bias_x: float, observed_y: bool = True) -> CalibrationSet:
    sig = np.array([1e-4, 1e-4 if observed_y else np.nan, np.nan])
    tc = TriadCalibration(TriadModel(bias=[bias_x, 0.5, 9.0]), {"bias": sig})
    return CalibrationSet(Unit(serial, "g"), {"accel": tc})


def test_statistics_and_a_robust_outlier():
    xs = [0.010, 0.011, 0.009, 0.0105, 0.0095, 0.050]
    stats = {(s.triad, s.field, s.index): s for s in coefficient_stats([_unit(f"U{i}", x) for i, x in enumerate(xs)])}
    bx = stats[("accel", "bias", (0,))]
    assert bx.n == 6 and bx.mean == pytest.approx(np.mean(xs)) and bx.std == pytest.approx(np.std(xs, ddof=1))
    med = np.median(xs)
    assert bx.median == pytest.approx(med)
    assert bx.robust_std == pytest.approx(1.4826 * np.median(np.abs(np.array(xs) - med)))
    # 0.05 is (0.05 - 0.01025) / (1.4826 * 0.00075) = 36 robust sigmas out; the others within 1.2
    assert [o[0] for o in bx.outliers] == ["U5"] and bx.outliers[0][2] > OUTLIER_Z
    assert ("accel", "bias", (2,)) not in stats  # never observed (NaN sigma): not a fleet statistic


def test_coefficients_observed_in_fewer_than_two_units_are_left_out():
    sets = [_unit("A", 0.01, observed_y=True), _unit("B", 0.02, observed_y=False)]
    keys = {(s.field, s.index) for s in coefficient_stats(sets)}
    assert ("bias", (0,)) in keys and ("bias", (1,)) not in keys


def test_identical_units_have_no_outliers():
    stats = coefficient_stats([_unit("A", 0.01), _unit("B", 0.01), _unit("C", 0.01)])
    assert all(s.robust_std == 0 and not s.outliers for s in stats)
