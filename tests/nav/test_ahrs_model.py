"""The AHRS filters' shared parts (workbench/nav/ahrs_model.py) against closed forms."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tests.nav.synthetic import FS, MAG_NED, table_run
from workbench.errors import AnalysisError
from workbench.nav.ahrs_model import (AhrsConfig, AhrsResult, Block, block_sizes, field_gate, initial_state,
                                      mag_white_noise, measure, residual_sigma)
from workbench.nav.strapdown import euler_rph, from_rph


def test_mag_white_noise_of_a_turning_field():
    # 20 000 samples of white noise 0.05 µT on a field turning at 10 °/s (second differences of the
    # field: (w dt)^2 |m| = 1.5e-4 µT, negligible). Relative sigma of the std of second differences
    # (lag-1, lag-2 correlations -2/3, 1/6): sqrt((1 + 2 (4/9 + 1/36)) / (2 N)) = 0.7 %; 5 sigma = 3.5 %
    rng = np.random.default_rng(3)
    n, sigma = 20_000, 0.05
    psi = np.radians(10.0) * np.arange(n) / FS
    field = 48.0 * np.stack([np.cos(psi), np.sin(psi), np.full(n, 0.5)], axis=1)
    est = mag_white_noise(field + rng.normal(0.0, sigma, (n, 3)))
    assert est == pytest.approx(np.full(3, sigma), rel=0.035)


@pytest.mark.parametrize("rph_deg", [(0.0, 0.0, 30.0), (10.0, -5.0, 200.0), (-20.0, 15.0, -90.0)])
def test_initial_state_levels_and_finds_heading_norm_and_dip(rph_deg):
    roll, pitch, heading = np.radians(rph_deg)
    samples, _ = table_run(from_rph(roll, pitch, heading), 2.0, 0, arw=0.0, vrw=0.0, mag_noise_ut=0.0)
    c, norm, dip = initial_state(samples, 0.0, int(FS))
    # noise-free: the only error is the Earth rate integrated into the 1-s window's rotation,
    # 7.3e-5 rad/s x 0.5 s = 3.6e-5 rad on average; 1e-4 rad bounds it
    err = (Rotation.from_matrix(c) * from_rph(roll, pitch, heading).inv()).magnitude()
    assert err < 1e-4
    assert norm == pytest.approx(np.linalg.norm(MAG_NED), rel=1e-9)
    assert dip == pytest.approx(np.radians(60.0), abs=1e-4)
    # a declination d (magnetic north d east of true north) turns the heading by +d
    c_d, _, _ = initial_state(samples, 0.1, int(FS))
    d_head = euler_rph(Rotation.from_matrix(c_d))[2] - euler_rph(Rotation.from_matrix(c))[2]
    assert np.angle(np.exp(1j * (d_head - 0.1))) == pytest.approx(0.0, abs=1e-9)


def _block(f, m) -> Block:
    f, m = np.asarray(f, float), np.asarray(m, float)
    eye = np.eye(3)
    return Block(eye[None], eye, np.zeros(3), 0.0, np.zeros((2, 3, 3, 3)), f, m, float(np.linalg.norm(f)),
                 float(np.hypot(m[0], m[1])))


def test_measure_is_the_tilt_and_wrapped_heading_innovation():
    g = 9.8
    tilt = 1e-3
    # specific force tilted east by 1 mrad: z_N = -f_E/|f| = -sin, z_E = f_N/|f| = 0
    z = measure(_block([0.0, g * np.sin(tilt), -g * np.cos(tilt)], [20.0, 0.0, 40.0]), 0.0)
    assert z == pytest.approx([-np.sin(tilt), 0.0, 0.0], abs=1e-15)
    # field at 179° east of north, declination -2°: atan2 - declination = 181° wraps to -179°
    m = 20.0 * np.array([np.cos(np.radians(179.0)), np.sin(np.radians(179.0)), 2.0])
    z = measure(_block([0.0, 0.0, -g], m), np.radians(-2.0))
    assert z[2] == pytest.approx(np.radians(-179.0), abs=1e-12)


def test_field_gate_thresholds_follow_the_expected_scatter():
    cfg = AhrsConfig()
    # 1-sigma of a 10-sample block's norm: sqrt(0.05^2 / 10) = 0.016 µT (no residual iron), with the
    # 0.3 µT floor -> 0.3004 µT; 5 sigma = 1.50 µT. Dip: 5 x hypot(0.016/48, 0.3°) = 0.0262 rad
    disturbed = field_gate(cfg, 0.05, 10, 48.0)
    dip0 = np.radians(60.0)

    def field(norm, dip):
        return _block([0.0, 0.0, -9.8], norm * np.array([np.cos(dip), 0.0, np.sin(dip)]))

    assert not disturbed(field(49.2, dip0), dip0) and disturbed(field(49.8, dip0), dip0)
    assert not disturbed(field(48.0, dip0 + 0.020), dip0) and disturbed(field(48.0, dip0 + 0.032), dip0)
    off = field_gate(replace(cfg, mag_rejection=False), 0.05, 10, 48.0)
    assert not off(field(60.0, 0.0), dip0)


def test_residual_sigma_slots():
    m = np.arange(9.0).reshape(3, 3)
    cfg = AhrsConfig(accel_bias_error=0.1, accel_scale_error=m, mag_bias_error_ut=np.array([1.0, 2.0, 3.0]),
                     mag_scale_error=0.5)
    r = residual_sigma(cfg)
    np.testing.assert_array_equal(r, np.concatenate([[0.1] * 3, m.ravel(), [1.0, 2.0, 3.0], [0.5] * 9]))


def test_block_sizes_and_refusals():
    samples, _ = table_run(Rotation.identity(), 3.0, 0)
    assert block_sizes(samples, AhrsConfig()) == (10, 100)  # 0.1 s and 1 s at 100 Hz
    with pytest.raises(AnalysisError, match="synthetic: the AHRS needs magnetometer columns"):
        block_sizes(replace(samples, mag=None), AhrsConfig())
    with pytest.raises(AnalysisError, match="synthetic: 110 samples are too few"):
        block_sizes(samples.slice(0, 110), AhrsConfig())


def test_disturbed_intervals_are_the_runs_of_flagged_epochs():
    t = np.arange(8) * 0.5
    flags = np.array([0, 1, 1, 0, 0, 1, 0, 1], bool)
    res = AhrsResult(t, Rotation.identity(8), np.zeros((8, 3)), np.zeros((8, 3)), np.zeros((8, 3)), np.zeros((8, 3)),
                     "kalman", np.ones(8), flags, (48.0, 1.0))
    assert res.disturbed_intervals() == [(0.5, 1.0), (2.5, 2.5), (3.5, 3.5)]


def test_result_protocol_end_state_in_lab_units():
    from workbench.result import AnalysisResult

    t = np.arange(4) * 0.1
    rph = np.tile(np.radians([1.0, -2.0, 30.0]), (4, 1))
    bias = np.tile(np.array([1.0, 2.0, 3.0]) * np.radians(1.0) / 3600.0, (4, 1))  # 1, 2, 3 °/h
    res = AhrsResult(t, Rotation.identity(4), rph, np.full((4, 3), np.radians(0.1)), bias, np.full((4, 3), np.nan),
                     "kalman", np.ones(4), np.array([0, 1, 1, 0], bool), (48.0, 1.0))
    assert isinstance(res, AnalysisResult)
    d = res.to_dict()
    assert d["rph"] == pytest.approx(list(np.radians([1.0, -2.0, 30.0]))) and d["gyro_bias_sigma"] == [None] * 3
    assert d["mag_disturbances"] == [[0.1, 0.2]] and d["t_end"] == pytest.approx(0.3)
    lines = res.summary()
    assert lines[0] == "kalman: roll, pitch, heading at 0.3 s: 1.000, -2.000, 30.000 ± 0.1, 0.1, 0.1 °"
    assert lines[1] == "kalman: gyro bias x 1 °/h, y 2 °/h, z 3 °/h"
    assert lines[2] == "kalman: field disturbed 0.2 s in 1 interval(s)"
