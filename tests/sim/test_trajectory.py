"""True land-vehicle kinematics (workbench/sim/trajectory.py) against closed forms.

(The S-curve limits, turn headings and the strapdown consistency of the rates and forces are in
tests/sim/test_vehicle.py.)
"""

import numpy as np
import pytest

from workbench.earth import EARTH_RATE, normal_gravity
from workbench.errors import WorkbenchError
from workbench.sim.trajectory import Limits, generate, leg_from_dict, s_curve

LAT, LON, H = np.radians(45.0), np.radians(10.0), 100.0


def test_distance_after_a_start_is_speed_times_time_less_half_the_ramp():
    """From rest to v along a point-symmetric S-curve of duration T the mean speed over the ramp is v/2,
    so at any time t after the ramp the distance is v (t - T/2) (Euler-Maclaurin trapezoid, exact
    for the piecewise quadratic speed up to its kinks: 1e-6 m)."""
    v, dur = 15.0, 60.0
    lim = Limits()
    _, _, _, ramp = s_curve(v, lim.accel, lim.jerk, np.zeros(1))
    tr = generate([leg_from_dict({"kind": "straight", "duration_s": dur, "speed_mps": v})], 100.0, LAT, LON, H)
    assert ramp == pytest.approx(v / lim.accel + lim.accel / lim.jerk)
    after = tr.t > ramp
    np.testing.assert_allclose(tr.distance[after], v * (tr.t[after] - ramp / 2), atol=1e-6)


def test_a_stopped_vehicle_senses_gravity_and_the_earth_rate():
    """At rest, level: |f| = normal gravity at the point, |w| = the Earth rate (rel 1e-12)."""
    tr = generate([leg_from_dict({"kind": "stop", "duration_s": 5.0})], 50.0, LAT, LON, H, heading0=0.7)
    np.testing.assert_allclose(np.linalg.norm(tr.f_b, axis=1), normal_gravity(LAT, H), rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(tr.omega_ib_b, axis=1), EARTH_RATE, rtol=1e-12)
    np.testing.assert_allclose(tr.f_b[:, 2], -normal_gravity(LAT, H), rtol=1e-12)  # body z down, level


def test_steady_turn_lever_arm_adds_the_centripetal_force():
    """1 m forward lever arm in a steady 6°/s turn at 10 m/s: the IMU senses an extra -r^2 l along x
    (centripetal towards the axle) plus cross terms with the Earth rate, 2 r Omega l ~ 1.5e-5 m/s^2:
    tolerance 1e-4 m/s^2 (the term itself is r^2 l = 1.1e-2 m/s^2)."""
    legs = [leg_from_dict(d) for d in ({"kind": "straight", "duration_s": 20.0, "speed_mps": 10.0},
                                       {"kind": "turn", "angle_deg": 180.0, "rate_dps": 6.0, "speed_mps": 10.0})]
    a = generate(legs, 50.0, LAT, LON, H)
    b = generate(legs, 50.0, LAT, LON, H, lever_arm=(1.0, 0.0, 0.0))
    r = np.radians(6.0)
    steady = (a.t > 20.0 + 3.0) & (a.t < a.t[-1] - 1.0)  # after the yaw-rate ramp (0.6 s at 0.1 rad/s^2)
    d = b.f_b[steady] - a.f_b[steady]
    np.testing.assert_allclose(d[:, 0], -r ** 2 * 1.0, atol=1e-4)
    np.testing.assert_allclose(d[:, 1:], 0.0, atol=1e-4)


@pytest.mark.parametrize("leg,match", [({"kind": "hover"}, "unknown kind 'hover'"),
                                       ({"kind": "turn", "angle_deg": 90, "speed_mps": 5}, "needs field 'rate_dps'"),
                                       ({"kind": "turn", "angle_deg": 90, "rate_dps": 0, "speed_mps": 5}, "rate_dps must be > 0"),
                                       ({"kind": "straight", "speed_mps": "fast", "duration_s": 3}, "not a number")])
def test_bad_legs_are_one_line_errors(leg, match):
    with pytest.raises(WorkbenchError, match=match):
        leg_from_dict(leg, "road leg 2")


def test_a_leg_too_short_for_its_speed_change_is_refused():
    """0 -> 20 m/s needs 20/1.5 + 1.5 = 14.8 s within the limits: a 5 s leg is refused, naming the leg."""
    with pytest.raises(WorkbenchError, match=r"road leg 0 .* shorter than the 14.8 s"):
        generate([leg_from_dict({"kind": "straight", "duration_s": 5.0, "speed_mps": 20.0})], 10.0, LAT, LON, H)
