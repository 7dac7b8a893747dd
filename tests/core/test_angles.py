"""Angle wrapping (workbench/angles.py) against closed forms: exact identities, no tolerances beyond
floating-point rounding of one addition of 2 pi (a few ulp of 2 pi, 1e-12 rad is ample)."""

import numpy as np
import pytest

from workbench.angles import angle_diff, circular_mean, wrap_2pi, wrap_pi

ULP = 1e-12  # rad: rounding of one +-2 pi shift


def test_wrap_pi_range_and_equivalence():
    rng = np.random.default_rng(0)
    a = rng.uniform(-50.0, 50.0, 1000)
    w = wrap_pi(a)
    assert np.all((w >= -np.pi) & (w < np.pi))
    # same direction: the difference is a whole number of turns
    turns = (a - w) / (2 * np.pi)
    assert np.abs(turns - np.round(turns)).max() < ULP
    assert isinstance(wrap_pi(3 * np.pi / 2), float)
    assert wrap_pi(3 * np.pi / 2) == pytest.approx(-np.pi / 2, abs=ULP)
    assert wrap_pi(np.pi) == pytest.approx(-np.pi, abs=ULP)  # half-open at +pi


def test_wrap_2pi_range_and_equivalence():
    rng = np.random.default_rng(1)
    a = rng.uniform(-50.0, 50.0, 1000)
    w = wrap_2pi(a)
    assert np.all((w >= 0) & (w < 2 * np.pi))
    turns = (a - w) / (2 * np.pi)
    assert np.abs(turns - np.round(turns)).max() < ULP
    assert wrap_2pi(-np.pi / 2) == pytest.approx(3 * np.pi / 2, abs=ULP)
    assert isinstance(wrap_2pi(1.0), float)


def test_angle_diff_across_the_branch():
    a = np.radians([179.0, -179.0, 10.0, 350.0])
    b = np.radians([-179.0, 179.0, 350.0, 10.0])
    assert np.degrees(angle_diff(a, b)) == pytest.approx([-2.0, 2.0, 20.0, -20.0], abs=1e-9)


def test_circular_mean_across_the_branch():
    # symmetric spread around 180 deg: the arithmetic mean would be ~0, the direction is pi
    a = np.radians([170.0, -170.0, 175.0, -175.0])
    assert abs(angle_diff(circular_mean(a), np.pi)) < ULP
    rng = np.random.default_rng(2)
    centre = 0.7
    draws = centre + rng.normal(0.0, 0.01, 10_000) + 2 * np.pi * rng.integers(-3, 4, 10_000)
    # 10 000 draws of sigma 0.01 rad: sigma of the mean 1e-4 rad; 5 sigma
    assert abs(circular_mean(draws) - centre) < 5e-4
