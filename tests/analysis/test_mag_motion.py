"""Magnetometer time offset, gyro bias and gravity tracked through a hand-held motion, against the virtual lab.

A continuous tumble (sim/handheld.py, still_s = 0, consumer_9axis grade) has no still stretch: gravity is known
only through the motion. The truth gives the gyro bias at the grade's temperature, the offset the test puts
into the magnetometer's labels, and the true down direction at every sample.
"""

import numpy as np
import pytest

from workbench.analysis import mag_ellipsoid, mag_motion
from workbench.analysis.mag_attitude import down_direction
from workbench.errors import AnalysisError
from workbench.grades import draw_unit, load_spec
from workbench.sim.handheld import handheld_session

SPEC = load_spec("consumer_9axis")
T_REF = 25.0


@pytest.fixture(scope="module", params=[5, 9])
def tumble(request):
    seed = request.param
    unit = draw_unit(SPEC, seed)
    session, truth = handheld_session(unit, seed, duration_s=60.0, still_s=0.0, temperature_c=T_REF)
    df = session.samples
    cols = {k: df[list(c)].to_numpy(float) for k, c in (("m", ("mx", "my", "mz")), ("g", ("gx", "gy", "gz")),
                                                          ("a", ("ax", "ay", "az")))}
    return df["t"].to_numpy(float), cols, truth


def _gyro_bias(truth) -> np.ndarray:
    """The true gyro output at zero rate (bias + g-sensitivity at 1 g, small) at T_REF, rad/s."""
    return truth.unit.gyro.apply(np.zeros((1, 3)), np.array([[0.0, 0.0, -9.81]]), np.full(1, T_REF))[0]


@pytest.mark.parametrize("delay_s", [0.0, 0.02])
def test_offset_and_gyro_bias_against_truth(tumble, delay_s):
    t, c, truth = tumble
    # the magnetometer's labels late by delay_s: the value labelled t was sensed at t - delay_s
    m = np.column_stack([np.interp(t - delay_s, t, c["m"][:, i]) for i in range(3)])
    rough = mag_ellipsoid.fit_algebraic_plain(m)
    timing = mag_motion.fit_timing([(t, m, c["g"], np.ones(len(t), bool))], rough.compensate)
    # 4 of the fit's own sigmas (Gauss-Newton, scaled by the residuals' correlation time): the misfit left is
    # the 20-mrad mag-to-IMU rotation and the gyro's scale errors, smooth in time, which the scaling covers
    assert abs(timing.delay_s - delay_s) < 4 * timing.delay_sigma
    assert timing.delay_sigma < 0.003  # 3 ms: a quarter of a 75-Hz magnetometer period
    assert np.all(np.abs(timing.gyro_bias() - _gyro_bias(truth)) < 4 * timing.bias_sigma)
    assert timing.significant == (delay_s > 0)


def test_gyro_gain_seen_by_the_field_against_truth(tumble):
    from scipy.spatial.transform import Rotation

    from workbench.analysis.mag_fit import polar_rotation

    t, c, truth = tumble
    rough = mag_ellipsoid.fit_algebraic_plain(c["m"])
    timing = mag_motion.fit_timing([(t, c["m"], c["g"], np.ones(len(t), bool))], rough.compensate)
    zero = np.zeros((3, 3))
    bm = truth.unit.mag.apply(zero, None, np.full(3, T_REF))[0]
    a_mag = (truth.unit.mag.apply(np.eye(3), None, np.full(3, T_REF)) - bm).T
    bg = truth.unit.gyro.apply(zero, zero, np.full(3, T_REF))[0]
    a_gyro = (truth.unit.gyro.apply(np.eye(3), zero, np.full(3, T_REF)) - bg).T
    # the rough (symmetric) ellipsoid leaves the mag's rotation U (I + M = P U) in its axes: h' = U h, and the gyro
    # reads A_g w + b_g, so the field turns at U A_g^-1 (w_meas - b_g): K = U A_g^-1, within 4 of its sigmas
    k_true = Rotation.from_rotvec(polar_rotation(a_mag)[1]).as_matrix() @ np.linalg.inv(a_gyro)
    assert timing.observes_gain and np.all(np.abs(timing.gain - k_true) < 4 * timing.gain_sigma)
    assert np.all(timing.gain_sigma < 0.01)


def test_gravity_tracked_through_the_motion_beats_the_accelerometer(tumble):
    t, c, truth = tumble
    a = truth.unit.accel.compensate(c["a"])
    d, tracked = mag_motion.track_down(t, a, c["g"] - _gyro_bias(truth), np.zeros(len(t), bool))
    true_down = truth.attitude.inv().apply(np.array([0.0, 0.0, 1.0]))

    def err(x):
        return np.degrees(np.arccos(np.clip(np.sum(x * true_down, axis=1), -1, 1)))
    # the accelerometer alone sees the lever arm (5 cm): |dw/dt x r + w x (w x r)| up to ~0.3 m/s^2 (~2°) at
    # these rates; the tracker averages it over tc = 1 s both ways. What is left is the centripetal term's
    # mean over tc (|w|^2 r averaged: ~0.1 m/s^2, 0.6°) and the gyro's scale errors (0.1 % of a 100° turn
    # within tc, cancelling between the passes to first order): rms under 0.5° and under 0.7x the accelerometer's
    assert tracked.mean() > 0.9  # no saturation: all but the first and last tc are tracked
    assert np.sqrt(np.mean(err(d)[tracked] ** 2)) < 0.5
    assert np.sqrt(np.mean(err(d)[tracked] ** 2)) < 0.7 * np.sqrt(np.mean(err(down_direction(a))[tracked] ** 2))


def test_a_saturated_gyro_restarts_the_tracker():
    t = np.arange(1000) / 100.0
    a = np.tile([0.0, 0.0, -9.81], (1000, 1))
    g = np.zeros((1000, 3))
    restart = np.zeros(1000, bool)
    restart[500] = True
    _, tracked = mag_motion.track_down(t, a, g, restart)
    # tracked: at least SETTLE_TC * tc = 1 s after the start / a restart and before the end / the next restart
    expect = ((t >= 1.0) & (t <= 3.99)) | ((t >= 6.01) & (t <= 8.99))
    assert np.array_equal(tracked, expect)


def test_a_record_without_rotation_gives_no_timing():
    t = np.arange(2000) / 100.0
    m = np.tile([20.0, 0.0, 40.0], (2000, 1)) + np.random.default_rng(1).normal(0, 0.2, (2000, 3))
    g = np.random.default_rng(2).normal(0, 1e-3, (2000, 3))
    with pytest.raises(AnalysisError, match="did not turn enough"):
        mag_motion.fit_timing([(t, m, g, np.ones(2000, bool))], lambda x: x)
