"""AXD-LNS dead reckoning (thesis ch. 2) against the simulated vehicle's truth."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.earth import radii
from workbench.errors import AnalysisError
from workbench.grades import draw_unit, load_spec
from workbench.nav.compensate import compensate, imu_samples, process_noise
from workbench.nav.lns import LnsConfig, error_statistics, run_lns
from workbench.nav.road import gps_fixes, odometer_distance
from workbench.session import Site, load_session
from workbench.sim.vehicle import drive, drive_config, load_truth_trajectory

# 60 s rest, ~6 min with GPS (SF +4 % from the stop at 125-155 s), GPS lost at 420 s, ~5 min without
ROAD = [dict(kind="stop", duration_s=60), dict(kind="straight", length_m=300, speed_mps=12),
        dict(kind="turn", angle_deg=90, rate_dps=8, speed_mps=9), dict(kind="straight", length_m=400, speed_mps=14),
        dict(kind="stop", duration_s=30),
        dict(kind="straight", length_m=900, speed_mps=15), dict(kind="turn", angle_deg=-120, rate_dps=8, speed_mps=9),
        dict(kind="straight", length_m=1200, speed_mps=15), dict(kind="turn", angle_deg=60, rate_dps=8, speed_mps=9),
        dict(kind="straight", length_m=2500, speed_mps=15), dict(kind="turn", angle_deg=-90, rate_dps=8, speed_mps=9),
        dict(kind="straight", length_m=1500, speed_mps=15), dict(kind="stop", duration_s=20)]
T_LOSS = 420.0
HEADING0_DEG = 270.0


@pytest.fixture(scope="module")
def lns_drive(tmp_path_factory):
    out = tmp_path_factory.mktemp("lns") / "session"
    unit = draw_unit(load_spec("quasi_tactical"), 4)
    road = [dict(leg) for leg in ROAD]
    cfg = drive_config(road, Site(40.9, 14.2, 50.0), HEADING0_DEG,
                       odometer={"scale_steps": [[140.0, 4.0]]}, gps={"sigma_h_m": 2.0})
    drive(cfg, unit, 4, out)
    return load_session(out), load_truth_trajectory(out), unit


def _run(lns_drive, make_calibration, **cfg):
    session, truth, unit = lns_drive
    cal = make_calibration(unit)
    samples = compensate(imu_samples(session.samples, session.sample_rate_hz), cal, ("gyro", "accel"))
    res = run_lns(samples, odometer_distance(session), gps_fixes(session), session.site.latitude,
                  process_noise(cal), LnsConfig(**{"gps_loss_s": T_LOSS, "gps_sigma": 2.0, **cfg}))
    k = np.searchsorted(truth["t"].to_numpy(), res.t)
    rm, rn = radii(truth["ref_lat"].to_numpy()[k])
    err = np.hypot((res.lat - truth["ref_lat"].to_numpy()[k]) * rm,
                   (res.lon - truth["ref_lon"].to_numpy()[k]) * rn * np.cos(res.lat))
    return res, truth, k, err, cal


def test_scale_factor_state_tracks_the_odometer_step_and_bounds_the_error(lns_drive, make_calibration):
    res, truth, k, err, _ = _run(lns_drive, make_calibration)
    j = int(np.searchsorted(res.t, T_LOSS)) - 1
    # the odometer reads +4 % (scale error s = 0.04) from the restart at 155 s. The SF random walk of
    # 0.2 %/√s (what lets the estimate follow a step within seconds, thesis Fig. 2.18) against 2 m fixes
    # at 15 m/s holds the filter's 1-sigma near 0.7 %: the estimate is within 3 of its own sigma
    assert res.sigma[j, 2] < 0.01
    assert res.odo_scale[j] == pytest.approx(0.04, abs=3 * res.sigma[j, 2])
    k_restart = np.searchsorted(res.t, 155.0)
    assert np.all(np.abs(res.odo_scale[k_restart:k_restart + 10]) < 0.03)  # still the old value at the restart
    assert res.odo_scale[k_restart + 30] > 0.03  # and ~4 % within half a minute
    # after the loss the error grows from the residual SF error (the estimate's ~0.5 % wander) and the
    # heading: within 3 sigma of the filter's own position covariance, and below 1 % of the ~2.6 km
    # without GPS (the thesis requirement is 3 %)
    d = truth["distance"].to_numpy()[k]
    sel = res.t >= T_LOSS
    stats = error_statistics(err[sel], d[sel] - d[sel][0], 1000.0)
    assert stats["distance_m"] > 2500 and stats["max"] < 1.0
    assert err[-1] < 3 * np.hypot(res.sigma[-1, 0], res.sigma[-1, 1])


def test_without_the_scale_factor_state_the_odometer_error_stays(lns_drive, make_calibration):
    res, truth, k, err, _ = _run(lns_drive, make_calibration, sf_state=False)
    assert np.all(np.isnan(res.odo_scale)) and np.all(np.isnan(res.sigma[:, 2]))
    sel = res.t >= T_LOSS
    lat, lon = truth["ref_lat"].to_numpy()[k][sel], truth["ref_lon"].to_numpy()[k][sel]
    rm, rn = radii(lat)
    disp = np.hypot((lat - lat[0]) * rm, (lon - lon[0]) * rn * np.cos(lat))
    # the uncorrected +4 % odometer error moves the position by 4 % of the displacement since the loss
    # (78 m here); the GPS phase has also bent the heading and the z-bias estimate to fit the long
    # odometer, which adds cross-track error (measured 110 m in all): at least the 4 %, and far outside
    # the filter's own covariance, which knows nothing of the odometer error
    final = err[sel][-1]
    assert final > 0.9 * 0.04 * disp[-1]
    assert final > 10 * np.hypot(res.sigma[-1, 0], res.sigma[-1, 1])


def test_bias_and_pitch_at_rest_and_the_course_over_ground_heading(lns_drive, make_calibration):
    res, truth, k, err, cal = _run(lns_drive, make_calibration)
    unit = lns_drive[2]
    true_residual = unit.model_of("gyro").bias[2] - cal.triads["gyro"].model.bias[2]
    # z bias from 59 s at rest: ARW 0.1 °/√h -> sigma of the mean 0.78 °/h; bias instability 0.77 °/h,
    # rate random walk 1 °/h/√h over the drive, misalignment x g-sensitivity residuals: 4 sigma ~ 6 °/h
    assert abs(res.gyro_bias[5] - true_residual) < np.radians(6.0) / 3600
    assert res.t_heading is not None and 60.0 < res.t_heading < 80.0  # 5 s above 3 m/s after starting
    # 30 s after the course-over-ground initialisation (3° prior; GPS velocity noise 0.1 m/s at 12 m/s is
    # 0.5° per fix) and until the loss, the heading is within 3 of the filter's own sigma (~0.2°)
    j = np.searchsorted(res.t, res.t_heading) + 30
    j1 = np.searchsorted(res.t, T_LOSS)
    heading_err = (res.heading[j:j1] - truth["heading"].to_numpy()[k][j:j1] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(heading_err).max() < 3 * res.sigma[j:j1, 3].max() < np.radians(1.0)


def test_a_180_degree_initial_heading_error_is_recovered_in_under_a_minute(lns_drive, make_calibration):
    """Thesis Fig. 2.14: started with the heading 180° off, the course over ground resets it."""
    res, truth, k, err, _ = _run(lns_drive, make_calibration, initial_heading=np.radians(HEADING0_DEG + 180.0))
    assert len(res.resets) >= 1
    t_move = 60.0
    heading_err = np.degrees((res.heading - truth["heading"].to_numpy()[k] + np.pi) % (2 * np.pi) - np.pi)
    ok = np.nonzero(np.abs(heading_err) > 2.0)[0]
    t_recovered = res.t[ok[-1] + 1] if len(ok) else res.t[0]
    assert t_recovered - t_move < 60.0
    assert err[(res.t > t_move + 60) & (res.t < T_LOSS)].max() < 15.0  # 2 m fixes, 3-sigma + lag


def test_no_gps_is_a_one_line_error(lns_drive, make_calibration):
    session, _, unit = lns_drive
    cal = make_calibration(unit)
    samples = imu_samples(session.samples, session.sample_rate_hz, "drive")
    with pytest.raises(AnalysisError, match="no GPS fixes"):
        run_lns(samples, odometer_distance(session), None, session.site.latitude, process_noise(cal))


def test_procedure_reports_seed_style_statistics(lns_drive, make_calibration):
    from procedures import lns_dead_reckoning as proc

    session, _, unit = lns_drive
    res = proc.analyze(session, make_calibration(unit), gps_loss_s=T_LOSS, gps_sigma_m=2.0)
    cal = res.result["calibrated"]
    assert cal["sf_state"]["error_pct"]["max"] < 1.0
    assert cal["no_sf_state"]["error_pct"]["mean"] > 2.0  # the +4 % odometer error, not estimated
    assert cal["sf_state"]["odo_scale_at_loss"] == pytest.approx(0.04, abs=0.005)
    # without the at-rest bias the +20 °/h set error turns the heading by 20 °/h over the 6 minutes
    assert res.result["wrong_bias"]["sf_state"]["error_pct"]["max"] > cal["sf_state"]["error_pct"]["max"]
    assert set(proc.figures(res)) == {"trajectory", "error_pct", "odo_scale"}


def test_a_bad_gps_file_is_a_one_line_error(tmp_path, lns_drive):
    import shutil

    from workbench.errors import SessionError

    session, _, _ = lns_drive
    copy = tmp_path / "drive"
    shutil.copytree(session.path, copy)
    gps = gps_fixes(session)
    gps.loc[3, "lat"] = np.nan
    (copy / "gps.parquet").unlink()
    gps.to_csv(copy / "gps.csv", index=False)
    with pytest.raises(SessionError, match=r"gps.csv: column lat: NaN or infinite value at row 3"):
        gps_fixes(load_session(copy))
