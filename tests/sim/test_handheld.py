"""The hand-held motion simulator (workbench/sim/handheld.py) against its truth, via an error-free unit.

With a perfect unit (no bias, scale, noise or LSB) the samples are the true inputs, which the test
recomputes independently from the truth attitude alone: Earth rate and gravity from
workbench/earth.py, the field from its dip and declination, the body rate from finite
differences of the attitude, the lever-arm force from the rigid-body formula. Tolerances are the
finite-difference truncation errors (derived at each assertion).
"""

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from workbench.earth import earth_rate_ned, gravity_ned
from workbench.grade_fixtures import load_spec
from workbench.grade_types import NoiseSpec
from workbench.grades import draw_unit
from workbench.model import TriadModel
from workbench.sim.handheld import handheld_session

LAT_DEG = 48.0
MOVE_S = 2.0


def _perfect_unit():
    unit = draw_unit(load_spec("consumer_9axis"), 7)
    return dataclasses.replace(unit, gyro=TriadModel(), accel=TriadModel(), mag=TriadModel(), gyro_noise=NoiseSpec(),
                               accel_noise=NoiseSpec(), mag_noise=NoiseSpec(), gyro_range=1e3, accel_range=1e3,
                               mag_range=1e4, gyro_hysteresis=None, accel_hysteresis=None, mag_hysteresis=None,
                               temp_sensor_noise_c=0.0)


@pytest.fixture(scope="module")
def held():
    unit = _perfect_unit()
    with_lever = handheld_session(unit, 5, duration_s=30.0, still_s=1.5, move_s=MOVE_S, latitude_deg=LAT_DEG)
    no_lever = handheld_session(unit, 5, duration_s=30.0, still_s=1.5, move_s=MOVE_S, latitude_deg=LAT_DEG,
                                lever_m=(0.0, 0.0, 0.0))
    return unit, with_lever, no_lever


def _body_rate(att: Rotation, fs: float) -> np.ndarray:
    """Central-difference body rate w.r.t. NED (N-2, 3), samples 1..N-2."""
    return (att[:-2].inv() * att[2:]).as_rotvec() * fs / 2.0


def test_still_samples_are_earth_rate_gravity_and_field_in_the_body_frame(held):
    """Exact (no motion): rel 1e-12 of the input, float rounding."""
    _, (session, truth), _ = held
    st = truth.still
    assert 0.3 < st.mean() < 0.6  # holds of 1.5 s between moves of 2 s
    lat = np.radians(LAT_DEG)
    inv = truth.attitude.inv()
    np.testing.assert_allclose(session.gyro()[st], inv[st].apply(earth_rate_ned(lat)), rtol=0, atol=1e-16)
    np.testing.assert_allclose(session.accel()[st], inv[st].apply(-gravity_ned(lat)), rtol=0, atol=1e-12)
    dip, dec = np.radians(60.0), np.radians(2.0)  # the defaults of handheld_session
    field = 48.0 * np.array([np.cos(dip) * np.cos(dec), np.cos(dip) * np.sin(dec), np.sin(dip)])
    np.testing.assert_allclose(session.mag(), inv.apply(field), rtol=0, atol=1e-12)
    # still means still: the attitude does not change within a hold
    idx = np.flatnonzero(st[1:] & st[:-1])
    assert np.abs((truth.attitude[idx].inv() * truth.attitude[idx + 1]).magnitude()).max() < 1e-12


def test_gyro_is_the_rate_of_the_truth_attitude(held):
    """Body rate from the central difference of the attitude: each move turns about one fixed body
    axis, so the difference of the angle theta s(t) is exact up to the truncation dt^2/6 d2w/dt2, with
    w = theta (2/T) sin^2(pi t/T) = (theta/T)(1 - cos(2 pi t/T)): |d2w/dt2| <= (theta/T)(2 pi/T)^2
    = 12 rad/s^3 for theta = 140 deg, T = 2 s; at 100 Hz dt^2/6 = 1.7e-5 s^2: 2.0e-4 rad/s. Tolerance
    1.5x that bound."""
    unit, (session, truth), _ = held
    fs = unit.sample_rate_hz
    lat = np.radians(LAT_DEG)
    rate = session.gyro()[1:-1] - truth.attitude[1:-1].inv().apply(earth_rate_ned(lat))
    bound = 1.5 * np.radians(140.0) / MOVE_S * (2 * np.pi / MOVE_S) ** 2 / fs ** 2 / 6
    assert np.abs(rate - _body_rate(truth.attitude, fs)).max() < bound
    assert np.abs(rate).max() > 0.5  # the hand does move (peak rate 2 theta / T >= 0.7 rad/s)


def test_each_move_turns_by_an_angle_in_the_drawn_range(held):
    """Rotation from the hold before a move to the hold after it: 40-140 deg (the default range), exact."""
    _, (_, truth), _ = held
    st = truth.still
    edges = np.flatnonzero(np.diff(st.astype(int)))
    starts, ends = edges[st[edges]], edges[~st[edges]] + 1  # last still sample before, first after
    starts, ends = starts[:len(ends)], ends[:len(starts)]
    assert len(starts) >= 7
    angles = np.degrees((truth.attitude[starts].inv() * truth.attitude[ends]).magnitude())
    assert np.all((angles >= 40.0 - 1e-9) & (angles <= 140.0 + 1e-9)), angles


def test_lever_arm_adds_the_rigid_body_acceleration(held):
    """The same motion (same seed) with and without the 5 cm lever: the difference of the accelerometer
    samples is dw/dt x r + w x (w x r), w the sampled gyro minus the Earth rate (the rate w.r.t. NED,
    checked above) and dw/dt its central difference. Truncation: dt^2/6 |d3w/dt3| r, |d3w/dt3| <=
    (theta/T)(2 pi/T)^3 = 38 rad/s^4: 1.7e-5 x 38 x 0.05 = 3.2e-5 m/s^2; tolerance 1e-4 m/s^2, 3x that (the lever term itself reaches
    w^2 r ~ 0.3 m/s^2). Not at the sample before and after a move's end: the second derivative of
    the rate jumps there (to 0), so the central difference is off by ~ dt |d2w/dt2| / 2 there instead."""
    unit, (s1, truth), (s0, _) = held
    fs = unit.sample_rate_hz
    r = np.array([0.05, 0.0, 0.0])
    gyro = s0.gyro() - truth.attitude.inv().apply(earth_rate_ned(np.radians(LAT_DEG)))
    w = gyro[1:-1]
    w_dot = (gyro[2:] - gyro[:-2]) * fs / 2.0
    expected = np.cross(w_dot, r) + np.cross(w, np.cross(w, r))
    diff = (s1.accel() - s0.accel())[1:-1]
    st = truth.still
    smooth = (st[:-2] == st[1:-1]) & (st[2:] == st[1:-1])
    assert smooth.mean() > 0.95
    assert np.abs(diff - expected)[smooth].max() < 1e-4
    assert np.abs(diff).max() > 0.05
