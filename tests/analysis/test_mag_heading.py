"""Tilt-compensated heading (workbench/analysis/mag_heading.py) against scipy's yaw of the true attitude.

Field in NED: 48 µT, dip 60°, declination 3°; the body field and down direction are the NED
vectors rotated into the body by random attitudes (pitch within ±75°, any roll and yaw).
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from workbench.analysis.mag_heading import evaluate_heading, heading, true_heading

DIP, DECL, B = np.radians(60.0), np.radians(3.0), 48.0
FIELD_NED = B * np.array([np.cos(DIP) * np.cos(DECL), np.cos(DIP) * np.sin(DECL), np.sin(DIP)])


def _attitudes(n: int, seed: int) -> Rotation:
    rng = np.random.default_rng(seed)
    yaw = rng.uniform(-np.pi, np.pi, n)
    pitch = rng.uniform(-np.radians(75), np.radians(75), n)
    roll = rng.uniform(-np.pi, np.pi, n)
    return Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll]))


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def test_heading_plus_declination_is_the_yaw_of_the_attitude():
    """Noise-free vectors: exact up to rounding (1e-9 rad at pitch <= 75°, where cos(pitch) >= 0.26)."""
    att = _attitudes(500, 1)
    h_b = att.inv().apply(FIELD_NED)
    d_b = att.inv().apply([0.0, 0.0, 1.0])
    yaw = att.as_euler("ZYX")[:, 0]
    np.testing.assert_allclose(_wrap(heading(h_b, d_b) + DECL - yaw), 0.0, atol=1e-9)
    np.testing.assert_allclose(_wrap(true_heading(att) - yaw), 0.0, atol=1e-12)


def test_known_and_estimated_declination():
    """Noise-free: with the true declination the error is 0; with 1° less it is -1° at every point;
    left to estimate, the declination is recovered (1e-9 rad)."""
    att = _attitudes(200, 2)
    h_b, d_b = att.inv().apply(FIELD_NED), att.inv().apply([0.0, 0.0, 1.0])
    ev = evaluate_heading(h_b, d_b, att, DECL)
    assert ev.rms < 1e-9 and not ev.declination_estimated
    ev = evaluate_heading(h_b, d_b, att, DECL - np.radians(1.0))
    np.testing.assert_allclose(ev.error, -np.radians(1.0), atol=1e-9)
    ev = evaluate_heading(h_b, d_b, att)
    assert ev.declination == pytest.approx(DECL, abs=1e-9) and ev.declination_estimated


def test_heading_noise_of_a_level_unit_is_field_noise_over_the_horizontal_field():
    """Level unit, white field noise s = 0.2 µT per axis: the heading error is the across-field
    horizontal noise over the horizontal field, std s / (B cos(dip)) = 8.3e-3 rad. The sample std of
    N = 4000 points has relative sigma 1/sqrt(2N) = 1.1 %; 4 sigma. Its mean is 0 within
    4 std / sqrt(N)."""
    rng = np.random.default_rng(3)
    n, s = 4000, 0.2
    att = Rotation.from_euler("z", rng.uniform(-np.pi, np.pi, (n, 1)))
    h_b = att.inv().apply(FIELD_NED) + rng.normal(0.0, s, (n, 3))
    d_b = np.tile([0.0, 0.0, 1.0], (n, 1))
    ev = evaluate_heading(h_b, d_b, att, DECL)
    expected = s / (B * np.cos(DIP))
    assert ev.std == pytest.approx(expected, rel=4 / np.sqrt(2 * n))
    assert abs(ev.mean) < 4 * expected / np.sqrt(n)


def test_points_pitched_beyond_80_degrees_are_left_out():
    att = Rotation.from_euler("ZYX", [[0.3, np.radians(p), 0.0] for p in (0.0, 45.0, 79.0, 81.0, -85.0)])
    h_b, d_b = att.inv().apply(FIELD_NED), att.inv().apply([0.0, 0.0, 1.0])
    ev = evaluate_heading(h_b, d_b, att, DECL)
    assert ev.error.size == 3
    np.testing.assert_allclose(np.degrees(ev.pitch), [0.0, 45.0, 79.0], atol=1e-9)
