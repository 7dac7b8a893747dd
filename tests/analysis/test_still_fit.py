"""Accelerometer and gyro bias from the still stretches of a hand-held record, against the unit's truth.

consumer_9axis unit turned by hand (sim/handheld.py): 24 holds of 3 s between 2-s tumbles, at the
grade's reference temperature. The detector finds the holds; the fits know no orientation.
"""

import numpy as np
import pytest

import procedures.multiposition as proc
from workbench.analysis.still_fit import G_SENSITIVITY_BOUND, fit_accel_norm, fit_gyro_bias, still_means
from workbench.errors import AnalysisError
from workbench.grades import draw_unit, load_spec
from workbench.sim.handheld import handheld_session

SPEC = load_spec("consumer_9axis")


@pytest.fixture(scope="module")
def held():
    unit = draw_unit(SPEC, 3)
    session, truth = handheld_session(unit, 3, duration_s=120.0, still_s=3.0, temperature_c=25.0)
    return session, truth, still_means(session)


def test_stretches_are_the_holds(held):
    session, truth, means = held
    assert len(means) == 24  # one per hold (the record starts with one)
    t = session.samples["t"].to_numpy()
    for m in means:  # every stretch lies inside a true hold
        assert truth.still[(t >= m.t0) & (t <= m.t1)].all()


def test_accel_norm_fit_matches_truth(held):
    session, truth, means = held
    fit = fit_accel_norm(means, session.site.gravity)
    u = truth.unit.accel
    # the norm sees the symmetric part of I + M (to first order sym(M)); the rotation part is not observable
    sym = (u.scale_misalignment + u.scale_misalignment.T) / 2
    # 4 sigma; the unit's nonlinearity (5000 ppm of 16 g full scale drawn per axis, ~1 mg at 1 g) is not in the
    # model and adds ~1 mg of bias-like error, i.e. under one sigma (sigma ~1.5 mg)
    assert np.all(np.abs(fit.bias - u.bias) < 4 * fit.bias_sigma)
    assert np.all(np.abs(fit.scale_misalignment - sym) < 4 * fit.scale_misalignment_sigma)


def test_gyro_bias_matches_truth(held):
    session, truth, means = held
    fit = fit_gyro_bias(means, session.site.latitude)
    u = truth.unit.gyro
    # what a still gyro shows besides the Earth rate: bias + g-sensitivity x specific force, averaged over the
    # stretches (sample-weighted, as the fit averages)
    n = np.array([m.n for m in means], float)
    f_mean = (np.array([m.accel for m in means]) * n[:, None]).sum(axis=0) / n.sum()
    expected = u.bias + (u.g_sensitivity @ f_mean if u.g_sensitivity is not None else 0.0)
    assert np.all(np.abs(fit.bias - expected) < 4 * fit.bias_sigma)


def test_gyro_bias_sigma_covers_the_unobserved_g_sensitivity():
    # 20 hand-held units of the grade (60 s, 3-s holds): the bias is compared with the true zero-g bias, so
    # the unfitted G f_mean (grade spread 0.1 °/s/g per element) must be in its sigma. 60 z-scores: the 1-sigma
    # coverage is at least 0.683 - 3 sqrt(0.683 * 0.317 / 60) = 0.50 for honest sigmas
    z = []
    for seed in range(20):
        session, truth = handheld_session(draw_unit(SPEC, seed), seed, duration_s=60.0, still_s=3.0,
                                          temperature_c=25.0)
        means = still_means(session)
        fit = fit_gyro_bias(means, session.site.latitude, SPEC.gyro.g_sensitivity)
        n = np.array([m.n for m in means], float)
        f_mean = (np.array([m.accel for m in means]) * n[:, None]).sum(axis=0) / n.sum()
        g_part = np.array(fit.notes["bias_sigma_g_sensitivity"])
        np.testing.assert_allclose(g_part, SPEC.gyro.g_sensitivity * np.linalg.norm(f_mean))
        z += list((fit.bias - truth.unit.gyro.bias) / fit.bias_sigma)
    assert np.mean(np.abs(z) < 1) >= 0.50
    assert "not observed" in fit.notes["g_sensitivity"]
    # a board of unknown grade: the consumer MEMS datasheet bound, 0.1 °/s/g at 1 g
    still = fit_gyro_bias(means[:1], session.site.latitude)
    np.testing.assert_allclose(still.notes["bias_sigma_g_sensitivity"],
                               G_SENSITIVITY_BOUND * np.linalg.norm(means[0].accel), rtol=1e-12)
    assert np.all(still.bias_sigma >= G_SENSITIVITY_BOUND * np.linalg.norm(means[0].accel))


def test_procedure_on_free_steps_and_too_few_orientations():
    unit = draw_unit(SPEC, 6)
    session, _ = handheld_session(unit, 6, duration_s=14.0, still_s=4.0)  # 3 holds only
    result = proc.analyze(session)
    assert "gyro" in result.calibration.triads and "accel" not in result.calibration.triads
    assert any("accelerometer not calibrated" in w and "3 still stretch" in w for w in result.warnings)
    with pytest.raises(AnalysisError, match="no still stretch"):
        fit_gyro_bias([], 0.8)
