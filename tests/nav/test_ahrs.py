"""Tests of the AHRS filters (workbench.nav.ahrs) on closed-form synthetic table runs."""

from __future__ import annotations

import numpy as np
import pytest

from tests.nav.synthetic import LAT, MAG_NED, NOISE, table_run
from workbench.errors import AnalysisError
from workbench.nav import ahrs
from workbench.nav.strapdown import attitude_errors, from_rph

MOUNT = from_rph(np.radians(10.0), np.radians(-5.0), 0.0)
GYRO_BIAS = np.array([1e-3, -5e-4, 8e-4])  # rad/s (~100-200 °/h)


def _profile(t):
    """20 °/s for 40-100 s, -45 °/s for 120-170 s, else still (rad/s)."""
    return np.where((t > 40) & (t < 100), np.radians(20.0), 0.0) + np.where((t > 120) & (t < 170),
                                                                             -np.radians(45.0), 0.0)


def _errors(res, att):
    idx = np.searchsorted(np.arange(len(att)) / 100.0, res.t)
    return np.degrees(attitude_errors(res.attitude, att[idx]))


@pytest.fixture(scope="module")
def clean():
    return table_run(MOUNT, 180.0, seed=21, gyro_bias=GYRO_BIAS, rate_profile=_profile)


@pytest.mark.parametrize("filt", ["kalman", "complementary"])
def test_calibrated_sensors_meet_the_accuracy(clean, filt):
    samples, att = clean
    res = ahrs.kalman(samples, NOISE, LAT) if filt == "kalman" else ahrs.complementary(samples, LAT)
    rms = np.sqrt(np.mean(_errors(res, att)[20:] ** 2, axis=0))  # after the first 2 s
    assert rms[2] < 1.0 and rms[0] < 0.2 and rms[1] < 0.2


def test_kalman_bias_and_sigma_are_honest(clean):
    samples, att = clean
    res = ahrs.kalman(samples, NOISE, LAT)
    assert np.all(np.abs(res.gyro_bias[-1] - GYRO_BIAS) < 3 * res.gyro_bias_sigma[-1])
    err = np.radians(_errors(res, att)[50:])
    # heading error against its 1-sigma (down axis): a consistent filter stays within 3 sigma ~99 % of the time
    assert np.mean(np.abs(err[:, 2]) < 3 * res.attitude_sigma[50:, 2]) > 0.95


def test_kalman_is_honest_with_a_residual_hard_iron():
    # A calibration leaves a hard iron of ~0.3 µT (1-sigma) on the 24 µT horizontal field: a heading
    # error of up to ~1° that turns with the table and is constant at rest, not white noise. Given
    # that sigma (coloured heading noise) the filter stays consistent: a consistent estimate is within
    # 3 sigma per axis with probability 99.7 % (fixed seed), and the heading error within its 3 sigma
    # at ~99 % of the epochs (> 95 % asserted, epochs being correlated).
    hard_iron = np.array([0.3, -0.3, 0.2])  # µT, a ~1-sigma draw of the residual
    samples, att = table_run(MOUNT, 180.0, seed=24, gyro_bias=GYRO_BIAS, rate_profile=_profile, mag_bias=hard_iron)
    res = ahrs.kalman(samples, NOISE, LAT, ahrs.AhrsConfig(mag_bias_error_ut=0.3))
    assert np.all(np.abs(res.gyro_bias[-1] - GYRO_BIAS) < 3 * res.gyro_bias_sigma[-1])
    err = np.radians(_errors(res, att)[50:])
    assert np.mean(np.abs(err[:, 2]) < 3 * res.attitude_sigma[50:, 2]) > 0.95
    # the same residual counted as absent (white noise only): the heading sigma is far too small
    naive = ahrs.kalman(samples, NOISE, LAT)
    assert np.mean(np.abs(err[:, 2]) < 3 * naive.attitude_sigma[50:, 2]) < 0.5


def test_hard_iron_shows_as_heading_error():
    # 5 µT horizontal hard iron on a 24 µT horizontal field: heading error up to asin(5/24) = 12°,
    # a sinusoid in the heading (RMS ~ 8.5°) while the table turns: "several degrees raw". With the
    # disturbance rejection on, a filter told the calibration is perfect sees the field's norm swing
    # by +-5 µT with the table angle and refuses it (compared below); without it the error shows.
    samples, att = table_run(MOUNT, 180.0, seed=22, gyro_bias=GYRO_BIAS, rate_profile=_profile,
                             mag_bias=np.array([5.0, 0.0, 0.0]))
    res = ahrs.kalman(samples, NOISE, LAT, ahrs.AhrsConfig(mag_rejection=False))
    # 5 µT against a norm gate of 5 x 0.3 µT: disturbed wherever the hard iron's projection on the
    # field exceeds 1.5 µT, i.e. most of the turning
    assert np.mean(ahrs.kalman(samples, NOISE, LAT).mag_disturbed) > 0.5
    rms = np.sqrt(np.mean(_errors(res, att)[20:] ** 2, axis=0))
    assert rms[2] > 3.0
    assert rms[0] < 0.2 and rms[1] < 0.2  # the magnetometer aids the heading only


def test_mag_white_noise_from_second_differences(clean):
    samples, _ = clean
    # 18000 samples: the std of a std estimate is ~1/sqrt(2 N) = 0.5 %; the table turning adds
    # second differences of |m| (w dt)^2 = 48 * (0.0079)^2 = 3e-3 µT, ~1 % of 0.05 µT in quadrature
    np.testing.assert_allclose(ahrs.mag_white_noise(samples.mag), 0.05, rtol=0.05)


def test_initial_attitude_while_turning():
    samples, att = table_run(MOUNT, 5.0, seed=23, rate_profile=lambda t: np.full_like(t, np.radians(30.0)))
    c0 = ahrs.initial_attitude(samples, 0.0, 100)
    from scipy.spatial.transform import Rotation

    before = Rotation.from_euler("z", -np.radians(30.0) * 0.01) * att[0]  # one sample before t = 0
    err = np.degrees(attitude_errors(Rotation.from_matrix(c0), before))
    assert np.all(np.abs(err) < 0.02)  # without de-rotation the 1 s average would be 15° off in heading


def test_ahrs_needs_a_magnetometer(clean):
    samples, _ = clean
    no_mag = type(samples)(samples.t, samples.gyro, samples.accel, None, None, samples.dt)
    with pytest.raises(AnalysisError, match="needs magnetometer"):
        ahrs.kalman(no_mag, NOISE, LAT)
    with pytest.raises(AnalysisError, match="needs magnetometer"):  # the other filter too
        ahrs.complementary(no_mag, LAT)



@pytest.fixture(scope="module")
def short():
    """75 s: still, 20 °/s for 20-40 s, still (a 75 s version of ``clean``, for the disturbance tests)."""
    return table_run(MOUNT, 75.0, seed=25, gyro_bias=GYRO_BIAS,
                     rate_profile=lambda t: np.where((t > 20) & (t < 40), np.radians(20.0), 0.0))


def _disturbed(samples, att, d_ned, starts=(25.0, 55.0), length_s=10.0):
    """``samples`` with a field ``d_ned`` (µT, NED) added for ``length_s`` from each of ``starts`` (a magnet near the unit)."""
    from dataclasses import replace

    mag = samples.mag.copy()
    for t0 in starts:
        sel = (samples.t >= t0) & (samples.t < t0 + length_s)
        mag[sel] += att[sel].inv().apply(np.asarray(d_ned, float))
    return replace(samples, mag=mag)


@pytest.mark.parametrize("filt", ["kalman", "complementary"])
def test_magnetic_transient_is_rejected(short, filt):
    # +15 µT east for 10 s on a 24 µT horizontal field, once while turning at 20 °/s (25-35 s) and once
    # at rest (55-65 s): a 32° heading step in the magnetometer (paper 004 Fig. 16, 20). Unrejected it
    # pulls the heading by tens of degrees; detected by the norm (+2.3 µT) and dip (-4.2°) against the
    # first second's (gate 5 x 0.3 µT, 5 x 0.3°), the heading runs on the gyros alone for 10 s:
    # 0.2 °/sqrt(h) ARW adds 0.01° and the Kalman filter's converged bias (sigma < 10 °/h) < 0.03°, so
    # its worst heading error is the undisturbed run's within 0.1°, far below the 1° required. The
    # complementary loop's bias (tau 20 s) has not converged at 25 s: its gyros drift more while unaided.
    samples, att = short
    run = (lambda s, cfg: ahrs.kalman(s, NOISE, LAT, cfg)) if filt == "kalman" \
        else (lambda s, cfg: ahrs.complementary(s, LAT, cfg))
    bad = _disturbed(samples, att, [0.0, 15.0, 0.0])
    base = np.abs(_errors(run(samples, ahrs.AhrsConfig()), att)[20:, 2]).max()
    off = np.abs(_errors(run(bad, ahrs.AhrsConfig(mag_rejection=False)), att)[20:, 2]).max()
    res = run(bad, ahrs.AhrsConfig())
    on = np.abs(_errors(res, att)[20:, 2]).max()
    assert off > 10.0
    assert on < 1.0
    assert filt == "complementary" or on < base + 0.1
    # the two transients' intervals, each to one update (0.1 s)
    np.testing.assert_allclose(res.disturbed_intervals(), [[25.0, 35.0], [55.0, 65.0]], atol=0.15)
    assert np.all(res.mag_weight[res.mag_disturbed] == 0.0)


def test_field_rotation_is_refused_by_the_innovation_gate(short):
    # The horizontal field turned by 5° for 10 s keeps norm and dip (the detection cannot see it);
    # the heading innovation of 5° is tens of sigma of the filter's (heading sigma ~0.05-0.1°), beyond
    # c1 = 6: the M-estimator (paper 001 eq. 46-47) gives it weight 0. Unrejected: ~4.4° excursion.
    from scipy.spatial.transform import Rotation

    samples, att = short
    d = Rotation.from_euler("z", 5.0, degrees=True).apply(MAG_NED) - MAG_NED
    bad = _disturbed(samples, att, d)
    res = ahrs.kalman(bad, NOISE, LAT)
    assert not np.any(res.mag_disturbed)
    assert np.abs(_errors(res, att)[20:, 2]).max() < 0.1
    inside = ((res.t > 25.2) & (res.t < 35.0)) | ((res.t > 55.2) & (res.t < 65.0))
    assert np.all(res.mag_weight[inside] == 0.0)
    off = ahrs.kalman(bad, NOISE, LAT, ahrs.AhrsConfig(mag_rejection=False))
    assert np.abs(_errors(off, att)[20:, 2]).max() > 3.0
