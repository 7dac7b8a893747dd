"""Strapdown mechanisation (workbench/nav/ins.py) against closed forms: WGS-84 radii, Rodrigues'
rotation (scipy), a unit at rest, and the Schuler oscillation of an initial velocity error.

(The mechanisation of the vehicle simulator's true rates and forces, and its 2nd-order
convergence, is tested in tests/sim/test_vehicle.py.)
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from workbench.earth import EARTH_RATE, WGS84_A, WGS84_B, earth_rate_ned, normal_gravity
from workbench.nav.ins import expm_so3, mechanise, radii


def test_radii_at_the_equator_and_the_pole():
    """Closed forms of the ellipse: equator R_M = b^2 / a, R_N = a; pole R_M = R_N = a^2 / b (rel 1e-12)."""
    rm, rn = radii(0.0)
    assert rm == pytest.approx(WGS84_B ** 2 / WGS84_A, rel=1e-12)
    assert rn == pytest.approx(WGS84_A, rel=1e-12)
    rm, rn = radii(np.pi / 2)
    assert rm == pytest.approx(WGS84_A ** 2 / WGS84_B, rel=1e-12)
    assert rn == pytest.approx(WGS84_A ** 2 / WGS84_B, rel=1e-12)


def test_expm_so3_is_scipys_rotation_of_the_rotation_vector():
    """Rodrigues vs scipy's rotvec, large angles and the small-angle series branch (|a| < 1e-8:
    the series error is th^4 / 120 ~ 1e-34, so both agree to rounding, 1e-14)."""
    rng = np.random.default_rng(2)
    for a in list(rng.normal(0, 1.0, (20, 3))) + list(rng.normal(0, 1e-9, (5, 3))) + [np.zeros(3)]:
        np.testing.assert_allclose(expm_so3(*a), Rotation.from_rotvec(a).as_matrix(), atol=1e-14)


def _at_rest(lat: float, h: float, n: int):
    """Error-free samples of a level unit at rest, body = NED: gyro = the Earth rate, accel = -g."""
    gyro = np.tile(earth_rate_ned(lat), (n, 1))
    accel = np.tile([0.0, 0.0, -float(normal_gravity(lat, h))], (n, 1))
    return gyro, accel


def test_unit_at_rest_stays_at_rest():
    """Error-free inputs of a unit at rest for 85 min at 10 Hz: the solution must stay put, far below
    the effect of the smallest sensor error that matters. 0.1 µg of accelerometer bias (a = 1e-6 m/s²)
    gives a Schuler-bounded horizontal error of up to 2 a / w_s^2 = 1.3 m and a tilt of a / g = 1e-7
    rad; tolerances 8 mm (0.6 % of that), 2e-5 m/s (a / w_s = 8e-4 m/s: 2.5 %) and 1e-8 rad (10 %)."""
    lat, h, fs, n = np.radians(45.0), 100.0, 10.0, 51_001
    gyro, accel = _at_rest(lat, h, n)
    s = mechanise(lat, 0.2, h, np.zeros(3), np.eye(3), gyro, accel, 1.0 / fs)
    rm, rn = radii(lat)
    north = (s.lat - lat) * (rm + h)
    east = (s.lon - 0.2) * (rn + h) * np.cos(lat)
    assert np.abs(north).max() < 8e-3 and np.abs(east).max() < 8e-3
    assert np.abs(s.v_ned[:, :2]).max() < 2e-5
    tilt = Rotation.from_matrix(s.c_bn).magnitude()
    assert tilt.max() < 1e-8


def test_initial_north_velocity_error_oscillates_with_the_schuler_period():
    """At the equator (no Foucault coupling: Omega sin(lat) = 0) a 0.1 m/s north velocity error of a
    unit at rest gives dN(t) = dv / w_s sin(w_s t), dv_N = dv cos(w_s t), w_s = sqrt(g / (R_M + h))
    (84.3 min; amplitude 80 m). Neglected by the linearised loop: the Earth-rate terms
    (Omega / w_s)^2 = 3.4e-3 of w_s^2, i.e. a phase of at most 2 pi 1.7e-3 = 1.1e-2 after one
    period: tolerance 1.5 % of the amplitudes. A missing transport rate (dN = dv t, 510 m) or the
    wrong radius of curvature (R_N: 0.34 % in w_s, 2 % of amplitude after a period) fails."""
    lat, h, fs = 0.0, 0.0, 10.0
    g = float(normal_gravity(lat, h))
    rm, _ = radii(lat)
    ws = np.sqrt(g / (rm + h))
    n = int(2 * np.pi / ws * fs) + 1  # one period
    gyro, accel = _at_rest(lat, h, n)
    dv = 0.1
    s = mechanise(lat, 0.0, h, np.array([dv, 0.0, 0.0]), np.eye(3), gyro, accel, 1.0 / fs)
    t = np.arange(n) / fs
    north = (s.lat - lat) * (rm + h)
    amp = dv / ws
    assert np.abs(north - amp * np.sin(ws * t)).max() < 0.015 * amp
    assert np.abs(s.v_ned[:, 0] - dv * np.cos(ws * t)).max() < 0.015 * dv
    assert EARTH_RATE / ws < 0.06  # the premise of the tolerance
