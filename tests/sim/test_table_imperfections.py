"""Turntable imperfections of the simulated rig (indexing error, wobble, axis tilt) against their settings."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from workbench.earth import normal_gravity
from workbench.jobs import simulate
from workbench.rigconfig import load_rig_config
from workbench.sequence import Hold, Rotate, Sequence
from workbench.sim.imperfections import Imperfections

RATE = np.radians(36.0)  # 10 s per revolution


@pytest.fixture(scope="module")
def rig():
    cfg = load_rig_config("sim")
    return replace(cfg, turntable=replace(cfg.turntable, positioning_error=0.0))


@pytest.fixture(scope="module")
def level(rig):
    """The level table's rotation (seed 4), the reference of the wobble and indexing tests."""
    return _rotating(rig, None)


def _rotating(rig, imp, seed=4):
    seq = Sequence("turn", [Rotate("z-down", RATE, revolutions=4)])
    s, truth = simulate(seq, "industrial_mems", seed=seed, rig=rig, imperfections=imp)
    x = s.step_samples(s.steps[0].index)
    return s, truth, x


def _line(y: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Least-squares [mean, cos, sin] amplitudes of ``y`` against the table angle."""
    a = np.column_stack([np.ones_like(theta), np.cos(theta), np.sin(theta)])
    return np.linalg.lstsq(a, y, rcond=None)[0]


def test_new_path_matches_the_level_table_when_its_errors_vanish(rig):
    # 1e-15 rad of indexing error takes the imperfect-table path; its attitude chain must give the
    # level table's samples to rounding (the off path is the unchanged code: numbers identical).
    seq = Sequence("mix", [Hold("x-up", np.radians(30.0), 2.0), Rotate("y-down", RATE, revolutions=1)])
    a, _ = simulate(seq, "industrial_mems", seed=2, rig=rig)
    b, _ = simulate(seq, "industrial_mems", seed=2, rig=rig, imperfections=Imperfections(table_indexing_error=1e-15))
    cols = ["gx", "gy", "gz", "ax", "ay", "az", "table_angle"]
    np.testing.assert_allclose(b.samples[cols].to_numpy(), a.samples[cols].to_numpy(), rtol=0, atol=1e-9)


def test_accelerometer_sees_the_axis_tilt_at_every_table_angle(rig, level):
    tilt = np.radians(0.5)
    s, truth, x = _rotating(rig, Imperfections(table_axis_tilt=tilt))
    g = normal_gravity(s.site.latitude, s.site.height_m)
    psi = (s.site.table_zero_azimuth or 0.0) + np.unwrap(x["table_angle"].to_numpy())
    # tilt about the base x axis puts -g sin(tilt) on the base y axis; in the platform it turns with the
    # table: ay = -g sin(tilt) cos(psi), ax = -g sin(tilt) sin(psi) (plus the unit's bias and misalignment)
    ax, ay = x["ax"].to_numpy(), x["ay"].to_numpy()
    base_y = ax * np.sin(psi) + ay * np.cos(psi)  # de-rotated to the base frame: a constant
    # noise of the mean: white noise over 40 s and the bias instability's wander (ADEV floor): 5 sigma;
    # the unit's own bias (turntable-averaged out: it turns with the platform) is removed by the rotation
    tol = 5 * np.hypot(np.max(truth.accel_noise.white) / np.sqrt(40.0), np.max(truth.accel_noise.bias_instability))
    assert base_y.mean() == pytest.approx(-g * np.sin(tilt), abs=tol + 0.02 * g * tilt)
    # the level table's mean is zero to the same noise
    s0, _, x0 = level
    psi0 = (s0.site.table_zero_azimuth or 0.0) + np.unwrap(x0["table_angle"].to_numpy())
    assert abs((x0["ax"] * np.sin(psi0) + x0["ay"] * np.cos(psi0)).mean()) < tol + 0.02 * g * tilt


def test_wobble_shows_at_the_rotation_frequency_in_the_base_frame(rig, level):
    w = np.radians(0.2)
    lines = []
    for s, truth, x in (level, _rotating(rig, Imperfections(table_wobble=w))):
        theta = np.unwrap(x["table_angle"].to_numpy())
        psi = (s.site.table_zero_azimuth or 0.0) + theta
        lines.append(_line(x["ax"].to_numpy() * np.sin(psi) + x["ay"].to_numpy() * np.cos(psi), theta))
    g = normal_gravity(s.site.latitude, s.site.height_m)
    # the axis rocks by w sin(theta): -g sin(w sin theta) ~ -g w sin(theta) on the base y axis, once per
    # revolution. The unit's own bias and misalignment turn with the platform and show at the same
    # frequency in the base frame, so the wobble is read against the level table with the same seed
    # (the same noise, sample for sample): what is left is the wobble through the unit's scale factor
    # and misalignment (< 0.5 %, 1 % allowed) and the second-order term of sin(w sin theta) (~1e-5).
    mean, cos_a, sin_a = lines[1] - lines[0]
    assert sin_a == pytest.approx(-g * w, rel=0.01)
    assert abs(cos_a) < 0.01 * g * w and abs(mean) < 0.01 * g * w


def test_indexing_error_modulates_the_true_rate_once_per_revolution(rig, level):
    a = np.radians(0.5)
    s, truth, x = _rotating(rig, Imperfections(table_indexing_error=a))
    theta = np.unwrap(x["table_angle"].to_numpy())
    # true angle theta + a sin(theta): the platform turns at RATE (1 + a cos theta) while the encoder
    # reads the commanded angle. 1-sigma of a line amplitude: ARW sqrt(fs) sqrt(2/N), plus the bias
    # instability; 5 sigma. The grade's scale factor (< 0.5 %) scales the amplitude: 1 % allowance.
    gz = x["gz"].to_numpy()
    mean, cos_a, sin_a = _line(gz, theta)
    n = len(gz)
    tol = 5 * np.hypot(np.max(truth.gyro_noise.white) * np.sqrt(truth.sample_rate_hz) * np.sqrt(2.0 / n),
                       np.max(truth.gyro_noise.bias_instability))
    assert cos_a == pytest.approx(RATE * a, abs=tol + 0.01 * RATE * a)
    assert abs(sin_a) < tol + 0.01 * RATE * a
    # the encoder column is the commanded motion: it does not see the error
    x0 = level[2]
    np.testing.assert_array_equal(x["table_angle"].to_numpy(), x0["table_angle"].to_numpy())


def test_table_errors_must_be_small_angles():
    from workbench.errors import WorkbenchError

    with pytest.raises(WorkbenchError, match="table_wobble"):
        Imperfections(table_wobble=1.0)
