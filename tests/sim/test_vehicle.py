"""The vehicle-trajectory simulator against closed forms and against its own strapdown integration."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from workbench.earth import earth_rate_ned, radii
from workbench.errors import WorkbenchError
from workbench.grades import draw_unit, load_spec
from workbench.nav.ins import mechanise
from workbench.nav.road import gps_fixes, odometer_distance
from workbench.session import Site, load_session
from workbench.sim.trajectory import generate, leg_from_dict, s_curve
from workbench.sim.vehicle import drive, drive_config, load_truth_trajectory

ROAD = [dict(kind="stop", duration_s=20), dict(kind="straight", duration_s=40, speed_mps=15),
        dict(kind="turn", angle_deg=90, rate_dps=10, speed_mps=10),
        dict(kind="straight", length_m=400, speed_mps=15, slope_deg=3),
        dict(kind="turn", angle_deg=-180, rate_dps=6, speed_mps=10),
        dict(kind="straight", length_m=600, speed_mps=20, slope_deg=-2), dict(kind="stop", duration_s=20)]
LAT, LON, H = np.radians(45.0), np.radians(10.0), 100.0


def _errors(tr, fs: float):
    """Max north/east/down position (m), velocity (m/s) and attitude (rad) error of the free strapdown."""
    s = mechanise(tr.lat[0], tr.lon[0], tr.h[0], tr.v_ned[0], tr.c_bn[0], tr.omega_ib_b, tr.f_b, 1.0 / fs)
    rm, rn = radii(tr.lat)
    pos = np.stack([(s.lat - tr.lat) * (rm + tr.h), (s.lon - tr.lon) * (rn + tr.h) * np.cos(tr.lat), tr.h - s.h], 1)
    att = Rotation.from_matrix(np.einsum("nji,njk->nik", tr.c_bn, s.c_bn)).magnitude()
    return np.abs(pos).max(), np.abs(s.v_ned - tr.v_ned).max(), att.max()


def test_s_curve_respects_limits_and_reaches_target():
    tau = np.linspace(-1, 30, 31001)
    v, d1, d2, total = s_curve(12.0, 1.5, 1.0, tau)
    assert abs(v[-1] - 12.0) < 1e-12 and np.abs(d1).max() <= 1.5 + 1e-12 and np.abs(d2).max() <= 1.0
    assert np.allclose(np.gradient(v, tau)[1000:-1000], d1[1000:-1000], atol=2e-3)  # d1 is the derivative
    assert total == pytest.approx(12.0 / 1.5 + 1.5)


def test_turns_end_on_the_commanded_heading_and_distance_matches_legs():
    legs = [leg_from_dict(d) for d in ROAD]
    tr = generate(legs, 100.0, LAT, LON, H, heading0=0.3)
    assert np.degrees(tr.heading[-1] - 0.3) == pytest.approx(-90.0, abs=1e-9)
    assert np.abs(np.diff(tr.speed)).max() * 100 <= 1.5 + 1e-9  # acceleration limit


def test_error_free_imu_output_integrates_back_to_the_truth():
    """Free strapdown (2nd-order scheme, nav/ins.py) of the simulator's true rates and forces.

    The remaining difference is the strapdown's own integration error: it shrinks ~4x from
    100 to 200 Hz (2nd order), so the simulator's forces and rates are consistent with its
    positions to far below any sensor error (a 1 °/h gyro bias alone moves the position by ~1 m
    over this 3.5-minute drive; 0.01 mg of accelerometer bias by 2 mm).
    """
    legs = [leg_from_dict(d) for d in ROAD]
    e100 = _errors(generate(legs, 100.0, LAT, LON, H, heading0=0.3), 100.0)
    e200 = _errors(generate(legs, 200.0, LAT, LON, H, heading0=0.3), 200.0)
    assert e100[0] < 5e-3 and e100[1] < 1e-4 and e100[2] < 2e-6
    assert e200[0] < e100[0] / 3 and e200[2] < e100[2] / 3
    # with a lever arm and a boresight: lever-arm velocity, centripetal/tangential terms, gravity gradient
    e = _errors(generate(legs, 100.0, LAT, LON, H, heading0=0.3, lever_arm=(1.0, -0.3, -0.5),
                         boresight=np.radians([0.5, 1.0, -2.0])), 100.0)
    assert e[0] < 1e-2 and e[1] < 3e-4 and e[2] < 2e-6


@pytest.fixture(scope="module")
def drive_session(tmp_path_factory):
    out = tmp_path_factory.mktemp("drive") / "session"
    cfg = drive_config(ROAD, Site(45.0, 10.0, 100.0), 30.0,
                       odometer={"scale_factor_pct": 1.0, "scale_steps": [[100.0, 5.0]], "pulse_m": 0.02},
                       gps={"outages": [[120.0, 150.0]], "sigma_h_m": 2.0})
    unit = draw_unit(load_spec("quasi_tactical"), 3)
    drive(cfg, unit, 3, out)
    return load_session(out), load_truth_trajectory(out), unit


def test_drive_session_odometer_and_gps(drive_session):
    session, truth, unit = drive_session
    assert {s.kind for s in session.steps} == {"drive"} and len(session.steps) == len(ROAD)
    odo = odometer_distance(session)
    assert np.all(np.diff(odo) >= -0.02 - 1e-9) and np.allclose(np.round(odo / 0.02) * 0.02, odo)  # whole pulses
    d = truth["distance"].to_numpy()
    t = truth["t"].to_numpy()
    # scale factor +1 % before 100 s, +5 % after. Tolerance: 2 pulses + speed noise 0.005 m/s/rtHz
    # over <= 80 s (0.045 m), relative to >= 400 m of travel: < 1e-4
    a, b = np.searchsorted(t, [20.0, 99.0])
    assert (odo[b] - odo[a]) / (d[b] - d[a]) - 1 == pytest.approx(0.01, abs=3e-4)
    a, b = np.searchsorted(t, [101.0, t[-1] - 1])
    assert (odo[b] - odo[a]) / (d[b] - d[a]) - 1 == pytest.approx(0.05, abs=1e-4)
    gps = gps_fixes(session)
    assert not np.any((gps["t"] >= 120) & (gps["t"] < 150)) and np.allclose(np.diff(gps["t"][:100]), 1.0)
    k = np.searchsorted(t, gps["t"].to_numpy())
    rm, _ = radii(truth["ref_lat"].to_numpy()[k])
    dn = (gps["lat"].to_numpy() - truth["ref_lat"].to_numpy()[k]) * rm
    # ~180 fixes of 2 m noise: the sample std is within 15 % (4 sigma of its ~5 % spread)
    assert np.std(dn) == pytest.approx(2.0, rel=0.2) and abs(np.mean(dn)) < 4 * 2.0 / np.sqrt(len(dn))


def test_drive_imu_is_the_unit_error_model_over_the_true_motion(drive_session):
    """At the first stop the gyro output minus the unit's true bias and the true Earth rate is noise."""
    session, truth, unit = drive_session
    rows = session.samples["t"].to_numpy() < 19.0
    gyro = session.samples[["gx", "gy", "gz"]].to_numpy()[rows]
    c_bn = Rotation.from_euler("ZYX", truth[["yaw", "pitch", "roll"]].to_numpy()[rows])
    w_true = c_bn.inv().apply(earth_rate_ned(LAT))
    true_out = unit.model_of("gyro").apply(w_true, session.samples[["ax", "ay", "az"]].to_numpy()[rows], 25.0)
    resid = (gyro - true_out).mean(axis=0)
    # ARW 0.1 °/√h = 2.9e-5 rad/√s over 19 s -> 6.7e-6 rad/s sigma of the mean: 5 sigma, plus
    # 2e-5 rad/s (4 °/h) for the bias instability (0.77 °/h) and rate random walk (1 °/h/√h)
    assert np.all(np.abs(resid) < 5 * 0.1 * np.pi / 180 / 60 / np.sqrt(19.0) + 2e-5)


def test_bad_road_is_a_one_line_error():
    with pytest.raises(WorkbenchError, match="road leg 1: unknown kind 'fly'"):
        drive_config([dict(kind="stop", duration_s=5), dict(kind="fly")], Site(45.0))
    with pytest.raises(WorkbenchError, match="road leg 1 .*shorter than"):
        generate([leg_from_dict(d) for d in (dict(kind="stop", duration_s=5),
                                             dict(kind="straight", duration_s=2, speed_mps=20))], 100.0, LAT, LON, H)
