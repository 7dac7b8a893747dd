"""The result protocol of the navigation results (LnsResult, ZuptResult, LandInsResult) on short simulated runs.

Each summary line is parsed back and compared with the result's fields (tolerance: the printed digits)
and with the simulation's truth (tolerance: the filter's own 1-sigma, derived per test); ``to_dict()``
must be strict JSON (``allow_nan=False``: NaN written as null) and SI.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from tests.nav.conftest import calibration_from_truth
from tests.nav.synthetic import ARW, LAT, NOISE, table_run
from workbench import units
from workbench.angles import wrap_pi
from workbench.earth import radii
from workbench.grades import draw_unit, load_spec
from workbench.nav import zupt
from workbench.nav.compensate import compensate, imu_samples, process_noise
from workbench.nav.land_ins import BG, GG, MAX_RUNGS, LandInsConfig, grade_errors, run_land_ins
from workbench.nav.lns import LnsConfig, run_lns
from workbench.nav.road import gps_fixes, odometer_distance
from workbench.nav.strapdown import euler_rph, from_rph
from workbench.result import AnalysisResult
from workbench.session import Site, load_session
from workbench.sim.vehicle import drive, drive_config, load_truth_trajectory

NUM = r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?"


def _nums(text: str) -> list[float]:
    """The numbers of ``text`` in order."""
    return [float(x) for x in re.findall(NUM, text)]


def _strict_json(d: dict) -> dict:
    """``d`` through strict JSON (raises on NaN / inf / numpy)."""
    return json.loads(json.dumps(d, allow_nan=False))


def _biases(line: str, unit_label: str) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis ``x v ± s <unit>`` of a summary line: values and sigmas in the printed unit."""
    found = re.findall(rf"([xyz]) ({NUM}) ± ({NUM}) {unit_label}", line)
    assert [a for a, _, _ in found] == list("xyz"), line
    return np.array([float(v) for _, v, _ in found]), np.array([float(s) for _, _, s in found])


# ZUPT alignment on the closed-form table run (tests/nav/synthetic.py): 120 s static, known attitude and bias
MOUNT = from_rph(np.radians(-3.0), np.radians(2.0), np.radians(30.0))
GYRO_BIAS = np.array([2e-4, -1e-4, 3e-4])  # rad/s


@pytest.fixture(scope="module")
def zupt_run():
    samples, att = table_run(MOUNT, 120.0, seed=3, gyro_bias=GYRO_BIAS, accel_bias=np.array([5e-4, -5e-4, 5e-4]))
    return zupt.align(samples, NOISE, LAT, float(euler_rph(MOUNT)[2]))


def test_zupt_summary_in_lab_units_matches_the_fields_and_the_truth(zupt_run):
    res = zupt_run
    # at rest the tilt is not observed apart from the horizontal accel bias: its sigma is the prior / g
    assert isinstance(res, AnalysisResult) and len(res.warnings) == 1 and not res.tilt_observed
    assert res.warnings[0].startswith("roll/pitch not observed apart from the horizontal accelerometer bias")
    att, vel, gyro, accel = res.summary()
    # attitude: three values to 0.001° then three 2-digit sigmas, in degrees
    assert att.startswith(f"ZUPT: roll, pitch, heading at {res.t[-1]:.1f} s:") and att.endswith(" °")
    vals = _nums(att.split(":", 2)[2])
    np.testing.assert_allclose(vals[:3], np.degrees(res.rph[-1]), atol=5e-4)
    np.testing.assert_allclose(vals[3:], np.degrees(res.attitude_sigma[-1]), rtol=0.05)
    # truth: 0.05 mg of accel bias implies a 5e-5 rad tilt, the 5 s levelling's noise 3.8e-5 rad and the
    # gyro-bias transient a few 1e-5 rad (tests/nav/test_zupt.py): 3.5e-4 rad (0.02°) bounds roll, pitch;
    # the heading is held at the true one given from outside, within 4 of its own sigma
    true = np.degrees(euler_rph(MOUNT))
    np.testing.assert_allclose(vals[:2], true[:2], atol=0.02)
    assert abs(vals[2] - true[2]) < 4 * vals[5]
    # velocity in mm/s (2 decimals) and the convergence time in whole seconds
    assert vel.startswith("ZUPT: |v_NED| ") and " mm/s, converged " in vel
    assert _nums(vel)[0] == pytest.approx(np.linalg.norm(res.velocity[-1]) * 1e3, abs=5e-3)
    assert _nums(vel)[1] == pytest.approx(round(res.convergence_time()), abs=0.5)
    # gyro bias in °/h: white noise only, so the estimate is the mean over ~115 s with sigma
    # ARW / sqrt(T); within 4 of the printed sigma of the truth
    g, gs = _biases(gyro, "°/h")
    np.testing.assert_allclose(g, units.to_unit(res.gyro_bias[-1], "deg/h"), rtol=1e-3)
    np.testing.assert_allclose(gs, units.to_unit(res.gyro_bias_sigma[-1], "deg/h"), rtol=0.05)
    np.testing.assert_allclose(gs, units.to_unit(ARW / np.sqrt(res.t[-1] - res.t_start), "deg/h"), rtol=0.35)
    assert np.all(np.abs(g - units.to_unit(GYRO_BIAS, "deg/h")) < 4 * gs)
    a, _ = _biases(accel, "mg")
    np.testing.assert_allclose(a, res.accel_bias[-1] / units.factor("mg"), rtol=1e-3, atol=1e-6)


def test_zupt_to_dict_is_strict_json_in_si(zupt_run):
    res = zupt_run
    d = _strict_json(res.to_dict())
    np.testing.assert_allclose(d["rph"], res.rph[-1])
    np.testing.assert_allclose(d["gyro_bias"], res.gyro_bias[-1])  # rad/s
    np.testing.assert_allclose(d["velocity"], res.velocity[-1])  # m/s
    assert d["t_start"] == res.t_start and d["convergence_time"] == res.convergence_time()
    assert d["measurements"] == list(res.measurements) and d["warnings"] == list(res.warnings)
    # the level against the accelerometers is what the ZUPT holds: far below the tilt's prior sigma
    assert d["tilt_observed"] is False and np.all(np.array(d["level_sigma"]) < 0.1 * np.array(d["attitude_sigma"][:2]))


# LNS: 40 s at rest, then ~70 s of road with GPS to the end; the odometer reads +2 %
LNS_ROAD = [dict(kind="stop", duration_s=40), dict(kind="straight", length_m=300, speed_mps=12),
            dict(kind="turn", angle_deg=90, rate_dps=8, speed_mps=9), dict(kind="straight", length_m=300, speed_mps=14),
            dict(kind="stop", duration_s=20)]


@pytest.fixture(scope="module")
def lns_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("lns_result") / "session"
    unit = draw_unit(load_spec("quasi_tactical"), 5)
    drive(drive_config(LNS_ROAD, Site(40.9, 14.2, 50.0), 270.0, odometer={"scale_factor_pct": 2.0},
                       gps={"sigma_h_m": 2.0}), unit, 5, out)
    session, truth = load_session(out), load_truth_trajectory(out)
    cal = calibration_from_truth(unit)
    samples = compensate(imu_samples(session.samples, session.sample_rate_hz), cal, ("gyro", "accel"))
    runs = {sf: run_lns(samples, odometer_distance(session), gps_fixes(session), session.site.latitude,
                        process_noise(cal), LnsConfig(gps_sigma=2.0, sf_state=sf)) for sf in (True, False)}
    return runs, truth


def test_lns_summary_in_lab_units_matches_the_fields_and_the_truth(lns_run):
    (runs, truth), res = lns_run, lns_run[0][True]
    assert isinstance(res, AnalysisResult)
    pos, head, sf, sig = res.summary()
    lat, lon, h = _nums(pos.split(":", 1)[1])
    assert pos.startswith(f"LNS at {res.t[-1]:.1f} s:") and pos.endswith(" m")
    assert (lat, lon) == pytest.approx(np.degrees([res.lat[-1], res.lon[-1]]), abs=5e-7)
    assert h == pytest.approx(res.h[-1], abs=0.05)
    # truth at the last step: with 2 m fixes to the end the position is within 4 of its own sigma (+ the 2 m
    # of one fix's noise the last step may still carry)
    k = np.searchsorted(truth["t"].to_numpy(), res.t[-1])
    rm, rn = radii(truth["ref_lat"].to_numpy()[k])
    dn = np.radians(lat - np.degrees(truth["ref_lat"].to_numpy()[k])) * rm
    de = np.radians(lon - np.degrees(truth["ref_lon"].to_numpy()[k])) * rn * np.cos(res.lat[-1])
    sn, se = _nums(sig.split("1-sigma", 1)[1])[:2]
    assert sig.startswith("LNS: position 1-sigma N ") and (sn, se) == pytest.approx(res.sigma[-1, :2], abs=0.05)
    assert abs(dn) < 4 * sn + 2.0 and abs(de) < 4 * se + 2.0
    assert f"GPS used in {int(res.gps_used.sum())} of {len(res.t)} steps" in sig
    # heading in ° with its sigma: the course over ground (0.1 m/s fixes at 9-14 m/s, < 1° per fix) keeps
    # the heading within 4 of the filter's sigma of the truth
    hd, hs, pitch, speed = _nums(head)
    assert hd == pytest.approx(np.degrees(res.heading[-1]), abs=5e-4)
    assert hs == pytest.approx(np.degrees(res.sigma[-1, 3]), rel=0.05)
    assert pitch == pytest.approx(np.degrees(res.pitch[-1]), abs=5e-4) and speed == pytest.approx(res.speed[-1],
                                                                                                    abs=5e-3)
    assert abs(np.degrees(wrap_pi(np.radians(hd) - truth["heading"].to_numpy()[k]))) < 4 * hs
    # odometer scale-factor error in % with its sigma: the +2 % within 4 of the printed sigma; the z-gyro
    # bias in °/h
    s, ss = _nums(sf.split("error", 1)[1])[:2]
    assert "%" in sf and s == pytest.approx(100 * res.odo_scale[-1], abs=5e-4)
    assert ss == pytest.approx(100 * res.sigma[-1, 2], rel=0.05) and abs(s - 2.0) < 4 * ss
    assert re.search(rf"gyro z bias {NUM} ± {NUM} °/h", sf)
    assert _nums(sf.split("gyro z bias", 1)[1])[0] == pytest.approx(units.to_unit(res.gyro_bias[-1], "deg/h"),
                                                                     rel=1e-3)


def test_lns_to_dict_is_strict_json_with_null_for_a_missing_state(lns_run):
    runs, _ = lns_run
    d = _strict_json(runs[True].to_dict())
    assert d["lat"] == runs[True].lat[-1] and d["heading"] == runs[True].heading[-1]  # rad
    assert d["odo_scale"] == pytest.approx(runs[True].odo_scale[-1]) and d["sigma"]["odo_scale"] > 0
    four = _strict_json(runs[False].to_dict())  # the 4-state filter has no scale-factor state: NaN -> null
    assert four["odo_scale"] is None and four["sigma"]["odo_scale"] is None
    assert "not estimated" in runs[False].summary()[2]


# land INS: 60 s at rest, 30 s at 10 m/s, 20 s at rest (tests/procedures/test_protocol_all.py's scale)
INS_LEGS = [{"kind": "stop", "duration_s": 60.0}, {"kind": "straight", "duration_s": 30.0, "speed_mps": 10.0},
            {"kind": "stop", "duration_s": 20.0}]


@pytest.fixture(scope="module")
def ins_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("ins_result") / "session"
    spec = load_spec("tactical_low_noise")
    unit = draw_unit(spec, 2)
    drive(drive_config(INS_LEGS, Site(40.0, 33.0, 900.0), 0.0), unit, 2, out)
    session, truth = load_session(out), load_truth_trajectory(out)
    cal = calibration_from_truth(unit)
    samples = compensate(imu_samples(session.samples, session.sample_rate_hz), cal, ("gyro", "accel"))
    res = run_land_ins(samples, np.radians(40.0), np.radians(33.0), 900.0, np.radians(0.3), grade_errors(spec),
                       LandInsConfig())
    return res, truth


def test_land_ins_summary_in_lab_units_matches_the_fields_and_the_truth(ins_run):
    res, truth = ins_run
    assert isinstance(res, AnalysisResult) and res.warnings == tuple(res.notes)
    pos, vel, att, gyro, accel, bore, modes = res.summary()
    lat, lon, h = _nums(pos.split(":", 1)[1].split("(")[0])
    sn, se = _nums(pos.split("1-sigma", 1)[1])
    assert (lat, lon) == pytest.approx(np.degrees([res.lat[-1], res.lon[-1]]), abs=5e-7)
    assert h == pytest.approx(res.h[-1], abs=0.05) and (sn, se) == pytest.approx(res.sigma[-1, :2], abs=0.05)
    # truth: within 4 of the filter's own sigma (+ 2 m of the set's unmodelled residual scale factor and
    # misalignment, tests/nav/test_land_ins.py)
    k = np.searchsorted(truth["t"].to_numpy(), res.t[-1])
    rm, rn = radii(truth["lat"].to_numpy()[k])
    assert abs(np.radians(lat) - truth["lat"].to_numpy()[k]) * rm < 4 * sn + 2.0
    assert abs(np.radians(lon) - truth["lon"].to_numpy()[k]) * rn * np.cos(res.lat[-1]) < 4 * se + 2.0
    np.testing.assert_allclose(_nums(vel), res.v_ned[-1], atol=5e-4)
    assert np.abs(_nums(vel)).max() < 0.05  # at rest at the end (ZUPT, 0.01 m/s sigma)
    a = _nums(att.split("heading", 1)[1])
    np.testing.assert_allclose(a[:3], np.degrees(res.rph[-1]), atol=5e-4)
    np.testing.assert_allclose(a[3:], np.degrees(res.sigma[-1, 6:9]), rtol=0.05)
    # heading from the 0.3° given (its sigma cfg.yaw0), within 4 sigma (+ 0.05° as in test_land_ins.py)
    assert abs(np.degrees(wrap_pi(np.radians(a[2]) - truth["yaw"].to_numpy()[k]))) < 4 * a[5] + 0.05
    g, gs = _biases(gyro, "°/h")
    np.testing.assert_allclose(g, units.to_unit(res.gyro_bias[-1], "deg/h"), rtol=1e-3, atol=1e-6)
    np.testing.assert_allclose(gs, units.to_unit(res.bias_sigma[-1, :3], "deg/h"), rtol=0.05)
    # the bias reported is the random constant plus the Gauss-Markov rungs of the bias instability: its sigma is
    # at most the parts' sum and at least the largest part minus the others (the triangle inequality of the
    # standard deviation; the split is weakly observed, so the parts are correlated)
    parts = np.vstack([res.sigma[-1, BG], res.sigma[-1, GG].reshape(MAX_RUNGS, 3)])
    total = parts.sum(axis=0)
    assert np.all((res.bias_sigma[-1, :3] <= total) & (res.bias_sigma[-1, :3] >= 2 * parts.max(axis=0) - total))
    _biases(accel, "mg")
    assert bore.count("mrad") == 2 and bore.endswith(" m")
    np.testing.assert_allclose(_nums(bore.split("lever arm", 1)[1]), res.lever_arm[-1], atol=5e-4)
    # update modes: percentages of the steps; ZUPT while the vehicle stands (80 of the 110 s)
    shares = dict(re.findall(rf"(\w+) ({NUM}) %", modes))
    for m in set(res.mode.tolist()):
        assert float(shares[m.upper() if m in ("zupt", "nhc") else m]) == pytest.approx(100 * np.mean(res.mode == m),
                                                                                      abs=0.5)
    assert float(shares["ZUPT"]) == pytest.approx(100 * 80 / 110, abs=10)


def test_land_ins_to_dict_is_strict_json_in_si(ins_run):
    res, _ = ins_run
    d = _strict_json(res.to_dict())
    assert d["lat"] == res.lat[-1] and d["h"] == res.h[-1]
    np.testing.assert_allclose(d["gyro_bias"], res.gyro_bias[-1])  # rad/s
    np.testing.assert_allclose(d["attitude_sigma"], res.sigma[-1, 6:9])
    assert sum(d["modes"].values()) == pytest.approx(1.0)
    assert "gyro_scale" not in d  # the 20-state filter has no scale-factor states (sigma NaN)
