"""Paper 001's land INS: NHC Jacobian, covariance analysis and the filter against the simulated drive."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from workbench.earth import radii
from workbench.grades import draw_unit, load_spec
from workbench.nav.compensate import compensate, imu_samples
from workbench.nav.land_ins import (BW, LA, V_, A_, LandInsConfig, cep, covariance_analysis, grade_errors,
                                    nhc_jacobian, run_land_ins)
from workbench.session import Site, load_session
from workbench.sim.roads import constant_rate_drive, precalibration_legs
from workbench.sim.trajectory import generate, leg_from_dict
from workbench.sim.vehicle import drive, drive_config, load_truth_trajectory

LAT, LON, H = np.radians(40.0), np.radians(33.0), 900.0


def test_cep_of_a_circular_gaussian_is_the_rayleigh_median():
    # Rayleigh median sigma sqrt(2 ln 2) = 1.1774 sigma; 200 000 draws: ~0.3 % relative spread
    assert cep(np.eye(2) * 4.0) == pytest.approx(2.0 * 1.17741, rel=0.01)


def test_nhc_jacobian_matches_finite_differences():
    c_bn = Rotation.from_euler("ZYX", [0.7, 0.05, -0.02]).as_matrix()
    v = np.array([12.0, 9.0, 0.3])
    w = np.array([0.01, -0.02, 0.15])
    bore = np.array([0.01, -0.02])
    lever = np.array([1.0, -0.4, 0.3])

    def vp(dv, dpsi, dw, dl):
        c = Rotation.from_rotvec(dpsi).as_matrix() @ c_bn
        c_bp = Rotation.from_rotvec([0.0, *dw]).as_matrix() @ Rotation.from_rotvec([0.0, *bore]).as_matrix()
        return nhc_jacobian(c, c_bp, v + dv, w, lever + dl)[0]

    c_bp0 = Rotation.from_rotvec([0.0, *bore]).as_matrix()
    v0, H = nhc_jacobian(c_bn, c_bp0, v, w, lever)
    eps = 1e-6
    for sl, size in ((V_, 3), (A_, 3), (BW, 2), (LA, 3)):
        for i in range(size):
            d = {"dv": np.zeros(3), "dpsi": np.zeros(3), "dw": np.zeros(2), "dl": np.zeros(3)}
            key = {V_.start: "dv", A_.start: "dpsi", BW.start: "dw", LA.start: "dl"}[sl.start]
            d[key][i] = eps
            num = (vp(**d) - v0) / eps
            # forward differences of step 1e-6: truncation ~ 1e-6 x the second derivative (|v| ~ 15 m/s)
            assert np.allclose(num, H[:, sl.start + i], atol=1e-4 * max(1, np.abs(num).max())), (key, i)


def _cruise(rate_dps: float, cruise_s: float = 900.0):
    legs = precalibration_legs(first_rest_s=120.0, stop_s=30.0) + [
        {"kind": "straight", "duration_s": 30.0, "speed_mps": 20.0},
        {"kind": "turn", "angle_deg": rate_dps * cruise_s, "rate_dps": rate_dps, "speed_mps": 20.0}
        if rate_dps else {"kind": "straight", "duration_s": cruise_s, "speed_mps": 20.0}]
    return [leg_from_dict(d) for d in legs]


def test_covariance_analysis_cep_falls_with_the_heading_change():
    """Paper 001 Fig. 4-4 / 4-5: the more the heading turns, the better NHC bounds the error."""
    ge = grade_errors(load_spec("tactical_low_noise"))
    ceps = [covariance_analysis(generate(_cruise(r), 1.0, LAT, LON, H), ge)["cep_m"] for r in (0.0, 0.2, 1.0)]
    assert ceps[0] > ceps[1] > ceps[2] > 0


@pytest.fixture(scope="module")
def ins_drive(tmp_path_factory):
    out = tmp_path_factory.mktemp("ins") / "session"
    unit = draw_unit(load_spec("tactical_low_noise"), 2)
    legs = precalibration_legs(first_rest_s=120.0, stop_s=30.0) + [
        {"kind": "straight", "duration_s": 30.0, "speed_mps": 20.0},
        {"kind": "turn", "angle_deg": 120.0, "rate_dps": 0.3, "speed_mps": 20.0}, {"kind": "stop", "duration_s": 20.0}]
    drive(drive_config(legs, Site(40.0, 33.0, 900.0), 0.0), unit, 2, out)
    return load_session(out), load_truth_trajectory(out), unit


@pytest.mark.parametrize("c0", [1.0, None])
def test_filter_error_stays_within_its_covariance(ins_drive, make_calibration, c0):
    session, truth, unit = ins_drive
    cal = make_calibration(unit)
    samples = compensate(imu_samples(session.samples, session.sample_rate_hz), cal, ("gyro", "accel"))
    spec = load_spec("tactical_low_noise")
    res = run_land_ins(samples, LAT, LON, H, np.radians(0.3), grade_errors(spec), LandInsConfig(c0=c0))
    k = np.searchsorted(truth["t"].to_numpy(), res.t)
    rm, rn = radii(truth["lat"].to_numpy()[k])
    dn = (res.lat - truth["lat"].to_numpy()[k]) * rm
    de = (res.lon - truth["lon"].to_numpy()[k]) * rn * np.cos(res.lat)
    # 4-sigma of the filter's own covariance on every axis at every step (the 20-state model leaves the
    # set's residual scale factor / misalignment (100 ppm, 0.1 mrad) out: a small, unmodelled extra)
    assert np.all(np.abs(dn) < 4 * res.sigma[:, 0] + 2.0) and np.all(np.abs(de) < 4 * res.sigma[:, 1] + 2.0)
    yaw = (res.rph[:, 2] - truth["yaw"].to_numpy()[k] + np.pi) % (2 * np.pi) - np.pi
    assert np.all(np.abs(yaw[10:]) < 4 * res.sigma[10:, 8] + np.radians(0.05))
    # validity logic: ZUPT exactly while the vehicle stands (the first step of each stop may miss)
    still = truth["speed"].to_numpy()[k] < 1e-3
    zupt = res.mode == "zupt"
    assert np.mean(zupt[still]) > 0.9 and not np.any(zupt & (truth["speed"].to_numpy()[k] > 0.5))
    assert np.all(res.mode[~still & (truth["speed"].to_numpy()[k] > 1.0)] == "nhc")


def test_procedure_runs_raw_and_calibrated(ins_drive, make_calibration):
    from procedures import land_ins as proc

    session, truth, unit = ins_drive
    res = proc.analyze(session, make_calibration(unit))
    cal, raw = res.result["calibrated"], res.result["raw"]
    assert cal["final_error_m"] is not None and cal["final_error_m"] < 4 * cal["final_sigma_m"] + 3.0
    # 26 % of the drive is standing still: the calibrated run finds the stops; the raw run's unmodelled
    # scale-factor and misalignment errors push its velocity beyond 2 sigma (eq. 43), so it loses some
    assert cal["zupt_fraction"] > 0.2 and cal["nhc_fraction"] > 0.5
    assert raw["zupt_fraction"] <= cal["zupt_fraction"] + 0.02
    assert set(proc.figures(res)) == {"horizontal_error"}


@pytest.fixture(scope="module")
def turning_raw_drive():
    # paper 001's tactical case at 1 °/s (table 4-1, trajectory 8): short pre-calibration, then 5 min at
    # 1 °/s; raw samples of a unit drawn with table 3-1's scale factor (150 ppm) and misalignment (1 mrad)
    unit = draw_unit(load_spec("tactical_low_noise"), 5)
    legs = precalibration_legs(first_rest_s=120.0, stop_s=30.0) + [
        {"kind": "straight", "duration_s": 30.0, "speed_mps": 20.0},
        {"kind": "turn", "angle_deg": 300.0, "rate_dps": 1.0, "speed_mps": 20.0}]
    session, truth = drive(drive_config(legs, Site(40.0, 33.0, 900.0), 0.0), unit, 5)
    return imu_samples(session.samples, session.sample_rate_hz), truth["trajectory"]


def _horizontal_z(res, tr) -> float:
    k = np.minimum(np.searchsorted(tr["t"].to_numpy(), res.t), len(tr) - 1)
    rm, rn = radii(tr["lat"].to_numpy()[k])
    dn = (res.lat - tr["lat"].to_numpy()[k]) * rm
    de = (res.lon - tr["lon"].to_numpy()[k]) * rn * np.cos(res.lat)
    return float(np.max(np.hypot(dn, de) / np.hypot(res.sigma[:, 0], res.sigma[:, 1]).clip(1.0)))


def test_scale_factor_states_keep_the_turning_tactical_case_consistent(turning_raw_drive):
    # At 1 °/s a 1 mrad misalignment is 3.6 °/h of cross-axis rate (3.6 sigma of the 1 °/h bias the 20
    # states allow), and in the pre-calibration's 10 °/s turns 36 °/h. On this drive the 20-state filter's
    # horizontal error reaches 5.4 sigma in the pre-calibration; with the gyro scale-factor and
    # misalignment states (29) 1.5 sigma. Bound: within 5 sigma at every step (a Rayleigh radius beyond
    # 5 sigma has p ~ 4e-6 per step; the margin over 3 sigma covers the heading's remaining
    # overconfidence, docs/navigation.md).
    samples, tr = turning_raw_drive
    spec = load_spec("tactical_low_noise")
    with29 = run_land_ins(samples, LAT, LON, H, 0.0, grade_errors(spec), LandInsConfig(states=29))
    assert _horizontal_z(with29, tr) < 5.0
    assert np.abs(with29.gyro_scale).max() > 0  # the states move
    with pytest.raises(ValueError, match="states=21"):
        run_land_ins(samples.slice(0, 500), LAT, LON, H, 0.0, grade_errors(spec), LandInsConfig(states=21))


@pytest.mark.parametrize("states", [20, 38])
def test_levelling_correlation_in_the_initial_covariance(states):
    # coarse levelling: delta psi_N = -e_E / g, delta psi_E = e_N / g with e the accelerometer's error at rest (bias,
    # bias-instability rungs, and with 38 states the scale factor and misalignment on gravity); the initial
    # covariance carries it, so the specific-force error g x tilt + e of the levelled horizontal axes has (near)
    # zero variance. 20 states: the misalignment on gravity is in the bias's variance instead (1 mrad reads 1 mg)
    from workbench.nav.land_ins import BA, GA, N_STATES, SA, _initial_covariance, rungs_of, scale_columns

    ge = grade_errors(load_spec("tactical_low_noise"))
    g = 9.80665
    for heading in (0.0, 0.7, 2.0):
        P = _initial_covariance(ge, LandInsConfig(tilt0=1e-9, states=states), heading)
        c, s = np.cos(heading), np.sin(heading)
        cbn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        # delta f_N = -g dpsi_E + (C e)_N, delta f_E = g dpsi_N + (C e)_E
        j = np.zeros((2, N_STATES))
        j[0, 7], j[1, 6] = -g, g
        j[:, BA] = cbn[:2]
        j[:, GA] = rungs_of(cbn[:2])
        if states == 38:
            j[:, SA] = cbn[:2] @ scale_columns(np.array([0.0, 0.0, -g]))
        assert np.abs(j @ P @ j.T).max() < 1e-12
        assert np.linalg.eigvalsh(P).min() > -1e-15
        bias = np.sqrt(np.diag(P)[BA])
        expected = ge.accel_bias if states == 38 else np.hypot(ge.accel_bias, g * np.array(
            [ge.accel_misalignment[0], ge.accel_misalignment[1], ge.accel_scale[2]]))
        np.testing.assert_allclose(bias, expected, rtol=1e-12)


def test_procedure_with_scale_factor_states(ins_drive, make_calibration):
    # -o states=29: the calibrated run's scale-factor states start from 2 x the set's sigmas (the raw run's
    # from raw_scale_prior_ppm / raw_misalignment_prior_mrad); the error stays within its covariance
    from procedures import land_ins as proc

    session, truth, unit = ins_drive
    res = proc.analyze(session, make_calibration(unit), states=29)
    cal = res.result["calibrated"]
    assert cal["final_error_m"] < 4 * cal["final_sigma_m"] + 3.0


def test_speed_test_guards():
    # eq. 43: |v| <= 2 sigma_v, passed below the creep speed (0.5 m/s: a velocity error beyond 2 sigma at a
    # stop no longer locks ZUPT out) and failed above zupt_max_speed (2 m/s: a 5 m/s sigma after an hour
    # unaided let ZUPTs in at 20 m/s on a straight road, where the gyro and acceleration tests pass)
    from workbench.nav.land_ins import speed_test

    cfg = LandInsConfig()
    assert speed_test(0.3, 0.01, cfg) and not speed_test(0.6, 0.01, cfg)
    assert speed_test(1.5, 1.0, cfg) and not speed_test(2.1, 5.0, cfg) and not speed_test(20.0, 12.0, cfg)


def _schuler_budget(s0: np.ndarray, ge, t: float, speed: float, lat: float) -> tuple[float, float]:
    """Closed-form 1-sigma (m) along and across a straight due-north cruise of ``t`` s at ``speed`` m/s
    after the pre-calibration, from the filter sigmas ``s0`` (38,) at its end, each error alone:
    along-track Schuler loop (Titterton & Weston ch. 12): east gyro bias ``R ε (t - sin ω_s t / ω_s)``,
    north accel bias ``b (1 - cos ω_s t) / ω_s²``, east tilt ``R ψ (1 - cos ω_s t)``, ARW, VRW and the
    bias random walks through the same kernels; across: NHC holds the lateral velocity at ``V ψ_D``,
    so heading ``V ψ t``, z gyro bias ``V ε t² / 2``, ARW ``V N √(t³/3)``, bias random walk
    ``V q √(t⁵/20)``."""
    from workbench.earth import normal_gravity

    rm, rn = radii(lat)
    r = np.sqrt(rm * rn)
    ws = np.sqrt(float(normal_gravity(lat, 0.0)) / r)
    u = np.linspace(0.0, t, 20001)

    def rms(f):
        return np.sqrt(np.trapezoid(f ** 2, u))

    along = [r * s0[13] * (t - np.sin(ws * t) / ws), s0[9] * (1 - np.cos(ws * t)) / ws ** 2,
             r * s0[7] * (1 - np.cos(ws * t)), r * ge.gyro_white[1] * rms(1 - np.cos(ws * u)),
             ge.accel_white[0] * rms(np.sin(ws * u)) / ws, r * ge.gyro_bias_rw[1] * rms(u - np.sin(ws * u) / ws),
             ge.accel_bias_rw[0] * rms((1 - np.cos(ws * u)) / ws ** 2)]
    across = [speed * s0[8] * t, speed * s0[14] * t ** 2 / 2, speed * ge.gyro_white[2] * np.sqrt(t ** 3 / 3),
              speed * ge.gyro_bias_rw[2] * np.sqrt(t ** 5 / 20)]
    return float(np.sqrt(np.sum(np.square(along)))), float(np.sqrt(np.sum(np.square(across))))


def test_straight_cruise_error_matches_the_closed_form_schuler_budget():
    """The covariance of the straight 1-h tactical cruise (paper 001 table 4-1, trajectory 1) against an
    independent closed form: the along-track Schuler and across-track heading error growth of every
    error left at the end of the pre-calibration. The closed form drops the residuals' correlations
    and the Earth-rate coupling of the channels: measured 1.0 % along, 0.1 % across (navigation grade:
    4.9 %, 3.0 %); 10 % allowed.
    The budget's parts, each source alone through the filter's gains, add up to the covariance. The closed
    form has random-walk kernels: the filter is told the bias instability as a random walk here."""
    ge = grade_errors(load_spec("tactical_low_noise"), bias_model="random_walk")
    tr = generate([leg_from_dict(d) for d in constant_rate_drive(0.0)], 1.0, LAT, LON, H)
    out = covariance_analysis(tr, ge, budget=True)
    k0 = int(np.searchsorted(out["t"], tr.t[tr.speed > 19.99][0]))  # the cruise starts (at 20 m/s, due north)
    along, across = _schuler_budget(out["sigma"][k0], ge, out["t"][-1] - out["t"][k0], 20.0, LAT)
    assert np.sqrt(out["p_end"][0, 0]) == pytest.approx(along, rel=0.10)
    assert np.sqrt(out["p_end"][1, 1]) == pytest.approx(across, rel=0.10)
    total = sum(out["budget"].values())
    np.testing.assert_allclose(total[:2, :2], out["p_end"][:2, :2], rtol=1e-6)
    # what sets it: the bias random walk of the grade (not in table 3-1) and the ARW, not table 3-1's
    # 1 °/h bias, which the pre-calibration has removed
    north = {k: np.sqrt(v[0, 0]) for k, v in out["budget"].items()}
    assert max(north, key=north.get) == "gyro bias random walk"
    assert north["gyro bias x, y (table 3-1)"] < 0.01 * np.sqrt(out["p_end"][0, 0])


def test_gauss_markov_bias_state_keeps_its_steady_state_through_the_discretisation():
    # without measurements every Gauss-Markov rung started at sigma^2 stays there: P = Phi P Phi + Q_k with the
    # second-order Phi and trapezoidal Q_k of eq. 11 at dt / T <= 1e-2 (the fastest rung, T = 98 s) is off by
    # O((dt / T)^2) relative; the rungs stay uncorrelated
    from workbench.nav.land_ins import GG, MAX_RUNGS, LandInsConfig, discretise, error_dynamics, state_index

    ge = grade_errors(load_spec("tactical_low_noise"))
    cfg = LandInsConfig()
    ix = state_index(cfg, ge)
    assert set(range(38, 38 + 6 * MAX_RUNGS)) <= set(ix) and len(ix) == 20 + 6 * MAX_RUNGS  # 20 + both ladders
    F, gqg = error_dynamics(np.eye(3), np.array([0.0, 0.0, -9.8]), np.zeros(3), LAT, H, ge, cfg)
    phi, q = discretise(F, gqg, 1.0)
    p = np.diag(ge.gyro_gm_sigma.ravel() ** 2)
    for _ in range(5000):
        p = phi[GG, GG] @ p @ phi[GG, GG].T + q[GG, GG]
    np.testing.assert_allclose(p, np.diag(ge.gyro_gm_sigma.ravel() ** 2), rtol=1e-4, atol=1e-20)
    assert np.allclose(np.diag(phi[GG, GG]), np.exp(-1.0 / ge.gyro_gm_tau.ravel()), rtol=0.0, atol=1e-6)


def test_filter_is_consistent_with_a_gauss_markov_gyro_bias_it_is_told():
    # units with white noise and turn-on biases only, plus a Gauss-Markov gyro bias of 1 °/h, T = 200 s (exact
    # AR(1) draw) the filter is told. Heading error / sigma after a short pre-calibration over 12 units: for a
    # consistent filter 12 rms(z)^2 ~ chi2(12), two-sided 99 % band [0.52, 1.53]. Measured 1.23 (the full
    # pre-calibration, other draws: 1.18; told a random walk of the same short-term density instead: 1.27)
    from dataclasses import replace

    from scipy.signal import lfilter
    from scipy.stats import chi2

    spec = load_spec("tactical_low_noise")
    sigma, tau = np.radians(1.0) / 3600, 200.0
    base = grade_errors(spec)
    ge = replace(base, gyro_gm_sigma=np.full(3, sigma), gyro_gm_tau=np.full(3, tau))
    legs = precalibration_legs(first_rest_s=120.0, stop_s=60.0)
    z = []
    for k in range(12):
        full = draw_unit(spec, 300 + k)
        unit = replace(full, gyro=type(full.gyro)(bias=full.gyro.bias), accel=type(full.accel)(bias=full.accel.bias),
                       gyro_noise=type(full.gyro_noise)(white=full.gyro_noise.white),
                       accel_noise=type(full.accel_noise)(white=full.accel_noise.white))
        session, truth = drive(drive_config(legs, Site(40.0, 33.0, 900.0), 0.0), unit, 300 + k)
        tr = truth["trajectory"]
        s = imu_samples(session.samples, session.sample_rate_hz)
        rng = np.random.default_rng(k)
        a = np.exp(-s.dt / tau)
        w = rng.standard_normal((len(s.t), 3)) * sigma * np.sqrt(1 - a * a)
        w[0] = rng.standard_normal(3) * sigma
        s = replace(s, gyro=s.gyro + lfilter([1.0], [1.0, -a], w, axis=0))
        res = run_land_ins(s, LAT, LON, H, 0.0, ge, LandInsConfig())
        i = min(int(np.searchsorted(tr["t"].to_numpy(), res.t[-1])), len(tr) - 1)
        z.append(((res.rph[-1, 2] - tr["yaw"].iloc[i] + np.pi) % (2 * np.pi) - np.pi) / res.sigma[-1, 8])
    lo, hi = np.sqrt(chi2.ppf([0.005, 0.995], 12) / 12)
    assert lo < np.sqrt(np.mean(np.square(z))) < hi, np.round(z, 2)


def _flicker_unit(spec, seed: int):
    """A unit of ``spec`` with its turn-on biases, white noise and the grade's bias instability B (the virtual
    IMU's flicker generator, flat ADEV from one sample to 1e5 s), no other error."""
    from dataclasses import replace

    from workbench.grade_types import NoiseSpec

    full = draw_unit(spec, seed)
    changes = {}
    for t in ("gyro", "accel"):
        n = full.noise_of(t)
        changes[t] = type(getattr(full, t))(bias=getattr(full, t).bias)
        changes[f"{t}_noise"] = NoiseSpec(white=n.white, bias_instability=n.bias_instability)
    return replace(full, **changes)


def _precalibration_heading_z(units: list, ge, cfg: LandInsConfig) -> None:
    """Assert that the heading error / sigma at the end of the full pre-calibration of each unit (drive seed
    1000 + k, raw samples) has its rms in the chi-square 99 % band of a consistent filter."""
    from scipy.stats import chi2

    z = []
    for k, unit in enumerate(units):
        session, truth = drive(drive_config(precalibration_legs(), Site(40.0, 33.0, 900.0), 0.0), unit, 1000 + k)
        tr = truth["trajectory"]
        res = run_land_ins(imu_samples(session.samples, session.sample_rate_hz), LAT, LON, H, 0.0, ge, cfg)
        i = min(int(np.searchsorted(tr["t"].to_numpy(), res.t[-1])), len(tr) - 1)
        z.append(((res.rph[-1, 2] - tr["yaw"].iloc[i] + np.pi) % (2 * np.pi) - np.pi) / res.sigma[-1, 8])
    lo, hi = np.sqrt(chi2.ppf([0.005, 0.995], len(z)) / len(z))
    assert lo < np.sqrt(np.mean(np.square(z))) < hi, np.round(z, 2)


def test_heading_is_consistent_with_flicker_bias_instability_through_the_ladder():
    # flicker (the simulator's cascade, not a Gauss-Markov process) of the tactical grade's B = 0.1 °/h on units
    # with turn-on biases and white noise; the filter told the grade (the default three-rung ladder). Heading
    # error / sigma after the full pre-calibration over 24 units: for a consistent filter 24 rms(z)^2 ~ chi2(24),
    # two-sided 99 % band [0.64, 1.38]. Measured 1.30 (unit 7 loses its stops, 3.4 sigma: docs/navigation.md);
    # over 40 units (benchmarks/land_ins_consistency.py) 1.15 with the ladder, 2.05 with one Gauss-Markov state
    spec = load_spec("tactical_low_noise")
    _precalibration_heading_z([_flicker_unit(spec, 1000 + k) for k in range(24)], grade_errors(spec), LandInsConfig())


def test_turn_noise_has_the_variance_of_the_constant_misalignment_after_the_coherence_angle():
    # a yaw turn at 10 °/s with the body axes on NED: the gyro's scale factor and misalignment (random constants
    # of the grade's sigmas) give the attitude error C W(omega) ds t, variance C W S W^T C^T t^2; the white noise of
    # turn_coherence_rad = theta_c has the same after t = theta_c / |omega| (exact: the density is constant here)
    from workbench.nav.land_ins import A_, error_dynamics, scale_columns

    ge = grade_errors(load_spec("tactical_low_noise"))
    theta = np.radians(90.0)
    w_ie = 7.292115e-5 * np.array([np.cos(LAT), 0.0, -np.sin(LAT)])
    w_nb = np.radians([0.0, 0.0, 10.0])
    f = np.array([0.0, 0.0, -9.8])
    args = (np.eye(3), f, np.zeros(3), LAT, H, ge)
    _, off = error_dynamics(*args, LandInsConfig(), w_nb + w_ie, f)
    _, on = error_dynamics(*args, LandInsConfig(turn_coherence_rad=theta), w_nb + w_ie, f)
    t = theta / np.linalg.norm(w_nb)
    w = scale_columns(w_nb)
    var_s = np.concatenate([ge.gyro_scale, np.repeat(ge.gyro_misalignment, 2)]) ** 2
    np.testing.assert_allclose((on - off)[A_, A_] * t, (w * var_s) @ w.T * t ** 2, rtol=1e-9)
    assert np.allclose(on[V_, V_], off[V_, V_])
    # a filter that carries the scale-factor states (29) has them as states, not as noise
    _, states = error_dynamics(*args, LandInsConfig(turn_coherence_rad=theta, states=29), w_nb + w_ie, f)
    np.testing.assert_array_equal(states, off)


def test_heading_is_consistent_with_every_error_of_the_grade_with_the_turn_noise():
    # units with every error of the tactical grade (draw_unit), the 20-state filter with the ladder and the gyro
    # scale factor and misalignment as turn noise coherent over 90°; heading error / sigma after the full
    # pre-calibration over 12 units within the chi-square 99 % band [0.52, 1.53]. Measured 1.25 (without the turn
    # noise 1.54 on these 12; over 40 units 1.14 against 1.43, benchmarks/land_ins_consistency.py)
    spec = load_spec("tactical_low_noise")
    _precalibration_heading_z([draw_unit(spec, 1000 + k) for k in range(12)], grade_errors(spec),
                              LandInsConfig(turn_coherence_rad=np.radians(90.0)))
