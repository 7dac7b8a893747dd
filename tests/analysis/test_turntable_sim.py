"""Accuracy of the turntable estimators on the simulated rig (issue 5 targets), fixed seeds.

Simulated industrial-MEMS unit (thesis table 1.1/1.2 noise), 100 Hz, rig positioning error
0.01° (fixtures/rigs/sim.yaml). Truth is the unit's model at the session's mean temperature
(the unit has thermal coefficients; the chamber holds 23 °C, t_ref is 25 °C). The slower sweep
over seeds and grades is benchmarks/turntable_accuracy.py.
"""

from __future__ import annotations

import numpy as np
import pytest

import procedures.multiposition as multiposition
import procedures.rate as rate
from workbench.grades import load_spec
from workbench.model import TriadModel
from workbench.jobs import simulate

MG = 9.80665e-3  # m/s^2
DEG_H = np.radians(1.0) / 3600.0  # rad/s


def effective(model: TriadModel, temperature_c: float) -> tuple[np.ndarray, np.ndarray]:
    """Bias and M of a truth model at ``temperature_c`` (its thermal terms applied)."""
    t = np.array([temperature_c])
    if model.thermal is None:
        return model.bias, model.scale_misalignment
    return (model.bias + model.thermal.bias_shift(t)[0],
            model.scale_misalignment + np.diag(model.thermal.scale_shift(t)[0]))


@pytest.fixture(scope="module")
def industrial():
    return load_spec("industrial_mems")


def test_accelerometer_accuracy_industrial_mems(industrial):
    """24 positions x 60 s: bias < 0.2 mg, SF < 200 ppm, misalignment < 0.2 mrad, residual < 1 mg.

    The misalignment limit needs more than six positions: each position's 0.01° fixture error
    tilts gravity by 0.17 mrad across the axis, so a 6-position estimate of M_ij has a
    1-sigma of 0.17 / sqrt(2) = 0.12 mrad; 24 positions bring it to ~0.06 mrad.
    """
    seq = multiposition.sequence(industrial, positions=24, dwell_s=60.0)
    session, truth = simulate(seq, industrial, seed=11)
    result = multiposition.analyze(session)
    fit = result.payload["accel"]
    bias, m = effective(truth.accel, float(session.samples["temp"].mean()))
    off = ~np.eye(3, dtype=bool)
    assert np.abs(fit.bias - bias).max() < 0.2 * MG
    assert np.abs(np.diag(fit.scale_misalignment - m)).max() < 200e-6
    assert np.abs((fit.scale_misalignment - m)[off]).max() < 0.2e-3
    after = fit.residuals[["after_x", "after_y", "after_z"]].to_numpy()
    assert np.abs(after).max() < 1.0 * MG
    # honest uncertainties: every estimate within 4 of its own sigma
    assert np.all(np.abs(fit.bias - bias) < 4 * fit.bias_sigma)
    assert np.all(np.abs(fit.scale_misalignment - m) < 4 * fit.scale_misalignment_sigma)
    assert np.all(np.abs(fit.nonlinearity - truth.accel.nonlinearity) < 4 * fit.nonlinearity_sigma)
    assert fit.outliers == ()


def test_gyro_rate_accuracy_industrial_mems(industrial):
    """Rate table at 5/20/50/90 % of 450 °/s: SF < 300 ppm, misalignment < 0.5 mrad, residual < 0.05 % FS."""
    seq = rate.sequence(industrial)
    session, truth = simulate(seq, industrial, seed=12)
    result = rate.analyze(session)
    fit, fs = result.payload["gyro"], result.payload["full_scale"]
    _, m = effective(truth.gyro, float(session.samples["temp"].mean()))
    off = ~np.eye(3, dtype=bool)
    assert np.abs(np.diag(fit.scale_misalignment - m)).max() < 300e-6
    assert np.abs((fit.scale_misalignment - m)[off]).max() < 0.5e-3
    after = fit.residuals[["after_x", "after_y", "after_z"]].to_numpy()
    assert np.abs(after).max() / fs < 0.05e-2
    assert np.all(np.abs(fit.scale_misalignment - m) < 4 * fit.scale_misalignment_sigma)
    assert np.all(np.abs(fit.nonlinearity - truth.gyro.nonlinearity) < 4 * fit.nonlinearity_sigma)
    assert np.all(np.abs(fit.asymmetry) < 4 * fit.asymmetry_sigma)  # the simulated unit has none


def test_gyro_bias_navigation_grade_with_earth_rate():
    """Navigation grade, 24 positions x 150 s (1 h): bias within 0.01 °/h, Earth rate modelled.

    ARW 0.005 °/sqrt(h) over 1 h of data gives a bias 1-sigma of ~0.005 °/h (plus the
    0.005 °/h bias instability): the 0.01 °/h target needs the hour. Without the Earth-rate
    projection the horizontal Earth rate (11 °/h at 40.8°) would bias the estimate.
    """
    spec = load_spec("navigation_grade")
    session, truth = simulate(multiposition.sequence(spec, positions=24, dwell_s=150.0), spec, seed=3)
    result = multiposition.analyze(session)
    fit = result.payload["gyro"]
    bias, _ = effective(truth.gyro, float(session.samples["temp"].mean()))
    assert "modelled" in fit.notes["earth_rate"]
    assert np.abs(fit.bias - bias).max() < 0.01 * DEG_H
    assert np.all(np.abs(fit.bias - bias) < 4 * fit.bias_sigma)
