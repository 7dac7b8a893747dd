"""Ferraris gyro fit (workbench/analysis/gyro_fit.py) against the virtual lab's truth.

The turns of a Ferraris session last T = 360° / rate; the body turns by the table's 360° and by
the Earth rate, whose vertical part (Omega_e sin 40.8° = 9.8 °/h) stays along the turn axis:
left out, it biases every scale factor by Omega_e sin(lat) T / 360° (15, 30, 61 ppm for 2, 4,
8-s turns), which is what the fit did before (navigation grade, 10 seeds: -15.1, -30.2, -60.2 ppm
mean error, z up to 77).

Tolerances: the navigation grade's nonlinearity (5 ppm of 500 °/s full scale, 1-sigma spread of
the units) makes the scale factor of a turn at rate w the effective ``s + n w`` (up to 1.8 ppm
1-sigma at 180 °/s); given the grade's nonlinearity as the option, the sigma includes it, and the
issue's target is every diagonal element within 3 sigma and within 5 ppm of the truth over 10
seeds and three turn durations (90 z-scores: P(any > 3 sigma) = 22 % for honest Gaussian
z-scores, so the 3-sigma bound is also checked through the chi-square of their squares).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import chi2

import procedures.ferraris as ferraris
from workbench import units
from workbench.analysis.gyro_fit import turn_earth_rate
from workbench.analysis.turntable import fit_accel, fit_gyro_static
from workbench.earth import EARTH_RATE
from workbench.grades import load_spec
from workbench.jobs import simulate

NAV = load_spec("navigation_grade")
NONLIN = float(NAV.gyro.nonlinearity[0] / units.factor("ppm/(deg/s)"))  # ppm/(°/s), the grade's 1-sigma


def _scale_truth(truth, session) -> np.ndarray:
    t = np.array([session.samples["temp"].mean()])
    return np.diag(truth.gyro.scale_misalignment) + truth.gyro.thermal.scale_shift(t)[0]


@pytest.mark.parametrize("rate_dps", [180.0, 90.0, 45.0])
def test_navigation_grade_scale_factor_within_3_sigma_and_5_ppm(rate_dps):
    errors, z = [], []
    for seed in range(1, 11):
        session, truth = simulate(ferraris.sequence(NAV, dwell_s=10.0, turn_rate_dps=rate_dps), NAV, seed=seed)
        gyr = ferraris.analyze(session, gyro_nonlinearity_ppm_per_dps=NONLIN).payload["gyro"]
        e = np.diag(gyr.scale_misalignment) - _scale_truth(truth, session)
        errors.append(e)
        z.append(e / np.diag(gyr.scale_misalignment_sigma))
    errors, z = np.concatenate(errors), np.concatenate(z)
    assert np.abs(errors).max() < 5e-6, np.abs(errors).max() * 1e6
    assert np.abs(z).max() < 3.0, np.abs(z).max()
    assert chi2.ppf(0.005, z.size) < np.sum(z**2) < chi2.isf(0.005, z.size), np.sqrt(np.mean(z**2))
    assert abs(errors.mean()) < 3 * errors.std() / np.sqrt(errors.size)  # no Earth-rate bias left


def test_earth_rate_of_a_turn_from_the_table_angle_and_from_the_accelerometer_agree():
    """Both ways of getting the Earth rate of a turn (the recorded table angle; gravity from the
    accelerometer for a hand-made turn) give the vertical part Omega_e sin(lat) T along the
    turn axis; the horizontal part of an evenly turned revolution averages out."""
    session, _ = simulate(ferraris.sequence(NAV, dwell_s=10.0, turn_rate_dps=90.0), NAV, seed=3)
    acc = fit_accel(session, None, "none", settle_s=0.0, position_sigma=0.0)
    no_table = replace(session, samples=session.samples.drop(columns=["table_angle"]))
    for step in session.steps_of_kind("rate"):
        f = acc.model().compensate(session.accel(step.index))
        rate = session.gyro(step.index)
        exact = turn_earth_rate(session, step, rate, f, modelled=True)
        hand = turn_earth_rate(no_table, step, rate, f, modelled=True)
        duration = len(rate) / session.sample_rate_hz
        vertical = EARTH_RATE * np.sin(session.site.latitude) * duration  # rad over the turn
        axis = -np.asarray(step.mount).T[:, 2]  # body direction of the table's up axis
        assert abs(abs(exact.integral @ axis) - vertical) < 1e-3 * vertical
        # the accelerometer's down direction is good to the fixture tilt (mrad): 1e-3 of the vertical part
        assert np.linalg.norm(hand.integral - exact.integral) < 2e-3 * vertical
        assert np.all(exact.variance == 0) and np.sqrt(hand.variance.max()) < 0.05 * vertical


def test_earth_rate_left_in_the_bias_widens_the_sigma_and_says_so():
    """earth_rate=ignore: the static fit leaves the Earth rate in b and G, so each turn's
    integral is off by up to Omega_e T; the sigma includes that bound (uniform: /sqrt 3)."""
    session, _ = simulate(ferraris.sequence(NAV, dwell_s=10.0, turn_rate_dps=45.0), NAV, seed=4)
    res = ferraris.analyze(session, earth_rate="ignore", gyro_nonlinearity_ppm_per_dps=NONLIN)
    gyr = res.payload["gyro"]
    bound = EARTH_RATE * 8.0 / (2 * np.pi)  # 93 ppm for an 8-s turn
    assert np.all(np.diag(gyr.scale_misalignment_sigma) > bound / np.sqrt(3) * 0.99)
    assert any("Earth rate not modelled in the turns" in w and "ppm" in w for w in res.warnings)
    modelled = ferraris.analyze(session, gyro_nonlinearity_ppm_per_dps=NONLIN).payload["gyro"]
    assert np.all(np.diag(modelled.scale_misalignment_sigma) < bound / 10)


def test_nonlinearity_not_given_is_a_warning_naming_the_turn_rate():
    session, _ = simulate(ferraris.sequence(NAV, dwell_s=5.0, turn_rate_dps=90.0), NAV, seed=2)
    res = ferraris.analyze(session)
    assert any("nonlinearity not observed" in w and "90°/s" in w for w in res.warnings)
    g = fit_gyro_static(session, None, "auto", settle_s=0.0)
    assert g.notes["earth_rate"].startswith("modelled")
