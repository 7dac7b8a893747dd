"""Tests of the ZUPT fine alignment (workbench.nav.zupt) on closed-form synthetic data."""

from __future__ import annotations

import numpy as np
import pytest

from tests.nav.synthetic import ARW, LAT, NOISE, table_run
from workbench.earth import gravity_ned
from workbench.errors import AnalysisError
from workbench.nav import zupt
from workbench.nav.strapdown import attitude_errors, coarse_level, euler_rph, from_rph

MOUNT = from_rph(np.radians(-3.0), np.radians(2.0), np.radians(30.0))
GYRO_BIAS = np.array([2e-4, -1e-4, 3e-4])  # rad/s (~40-60 °/h)


def _implied_tilt_error(accel_bias):
    """Roll, pitch error (rad) that levelling with biased accelerometers implies (closed form)."""
    f = MOUNT.inv().apply(-gravity_ned(LAT)) + accel_bias
    return np.array(coarse_level(f[None, :])) - euler_rph(MOUNT)[:2]


@pytest.mark.parametrize("accel_bias, label", [(np.array([5e-4, -5e-4, 5e-4]), "calibrated (0.05 mg)"),
                                               (np.array([0.05, -0.03, 0.04]), "raw (5 mg)")])
def test_alignment_holds_the_levelled_attitude_and_finds_the_gyro_bias(accel_bias, label):
    samples, att = table_run(MOUNT, 180.0, seed=1, gyro_bias=GYRO_BIAS, accel_bias=accel_bias)
    res = zupt.align(samples, NOISE, LAT, float(euler_rph(MOUNT)[2]))
    err = attitude_errors(res.attitude, att[0])
    implied = _implied_tilt_error(accel_bias)
    # levelling over 5 s: tilt noise VRW / (g sqrt(5 s)) = 3.8e-5 rad; the ZUPT velocity then pins the
    # tilt / accel-bias combination. 3.5e-4 rad (0.02°) leaves ~9 sigma for the gyro-bias transient.
    np.testing.assert_allclose(err[-1, :2], implied, atol=3.5e-4, err_msg=label)
    i60 = np.searchsorted(res.t - res.t_start, 60.0)
    if np.abs(implied).max() < np.radians(0.01):  # a calibrated unit meets the thesis requirement
        assert np.all(np.abs(np.degrees(err[i60:, :2])) < 0.05)
    else:  # the raw bias shows as the tilt error it implies
        assert np.degrees(np.abs(err[-1, :2])).max() > 0.1
    late = (res.t - res.t_start) >= 120.0
    assert np.linalg.norm(res.velocity[late], axis=1).max() < 0.01
    # gyro bias: white noise only, so the estimate is the mean over ~175 s, sigma ARW / sqrt(T)
    sigma_expected = ARW / np.sqrt(res.t[-1] - res.t_start)
    np.testing.assert_allclose(res.gyro_bias_sigma[-1], sigma_expected, rtol=0.35)
    assert np.all(np.abs(res.gyro_bias[-1] - GYRO_BIAS) < 3 * res.gyro_bias_sigma[-1])
    assert res.convergence_time() is not None and res.convergence_time() < 60.0


def test_horizontal_accel_bias_stays_unobserved():
    # tilt and horizontal accel bias are inseparable at rest: their sigma must stay at the prior
    # (a level mount, so body x, y are horizontal and body z vertical)
    level = from_rph(0.0, 0.0, np.radians(30.0))
    samples, _ = table_run(level, 120.0, seed=2, accel_bias=np.array([0.01, 0.0, 0.0]))
    cfg = zupt.ZuptConfig(accel_bias_prior=0.05)
    res = zupt.align(samples, NOISE, LAT, np.radians(30.0), config=cfg)
    assert np.all(res.accel_bias_sigma[-1][:2] > 0.9 * 0.05)
    assert res.accel_bias_sigma[-1][2] < 0.01 * 0.05  # the vertical one is observed


def test_zarupt_mode_estimates_the_gyro_bias():
    samples, _ = table_run(MOUNT, 150.0, seed=3, gyro_bias=GYRO_BIAS)
    cfg = zupt.ZuptConfig(measurements=("position", "velocity", "heading", "zarupt"), zarupt_window_s=1.0)
    res = zupt.align(samples, NOISE, LAT, float(euler_rph(MOUNT)[2]), config=cfg)
    # the same gyro data reaches the filter twice (ZARUPT and the mechanisation), so its sigma is
    # optimistic by up to sqrt(2): test against the white-noise limit ARW / sqrt(T) instead
    tol = 3 * ARW / np.sqrt(res.t[-1] - res.t_start)
    assert np.all(np.abs(res.gyro_bias[-1] - GYRO_BIAS) < tol)
    assert res.weights.shape[1] == 10


def test_gain_scaling_rejects_an_outlier():
    samples, att = table_run(MOUNT, 60.0, seed=4, gyro_bias=GYRO_BIAS)
    kick = samples.accel.copy()
    kick[3000:3010] += [0.0, 5.0, 0.0]  # a 0.1 s knock of 0.5 g: a non-static interval
    knocked = type(samples)(samples.t, samples.gyro, kick, None, None, samples.dt)
    res = zupt.align(knocked, NOISE, LAT, float(euler_rph(MOUNT)[2]))
    k = np.searchsorted(res.t, 30.5)
    assert res.weights[k].min() == 0.0  # the velocity innovation of that second is beyond c1 = 6 sigma
    assert np.linalg.norm(res.velocity[-1]) < 0.01


def test_too_short_and_bad_options_are_refused():
    samples, _ = table_run(MOUNT, 6.0, seed=5)
    with pytest.raises(AnalysisError, match="too short"):
        zupt.align(samples, NOISE, LAT, 0.0)
    with pytest.raises(AnalysisError, match="unknown measurement"):
        zupt.ZuptConfig(measurements=("velocity", "gps"))


def test_thesis_attitude_hold_with_a_constant_accel_bias():
    # eq. 3.57 holds roll, pitch and heading at the frozen solution; with the levelling tilt
    # modelled (z = dtheta + S db_a) it is consistent while the accel bias is constant
    bias = np.array([0.01, -0.02, 0.03])
    samples, att = table_run(MOUNT, 150.0, seed=6, gyro_bias=GYRO_BIAS, accel_bias=bias)
    cfg = zupt.ZuptConfig(measurements=("position", "velocity", "attitude"))
    res = zupt.align(samples, NOISE, LAT, float(euler_rph(MOUNT)[2]), config=cfg)
    np.testing.assert_allclose(attitude_errors(res.attitude, att[0])[-1, :2], _implied_tilt_error(bias), atol=3.5e-4)
    assert np.all(np.abs(res.gyro_bias[-1] - GYRO_BIAS) < 3 * res.gyro_bias_sigma[-1])
    assert np.all(res.weights[-30:] > 0)
