"""Tests of workbench.analysis.northfinding: closed forms, least squares, maytag statistics, carousel,
redundant pairings, bad input, and the procedures through the simulator.

Statistical tests generate only the static (or rotating) samples the estimators use, at a low
sample rate (white noise density and flicker level set the position means, not the rate), with
the grade's noise generator (workbench.sim.noise.NoiseProcess), so 40 pairs x 10 seeds run in
well under a second. Tolerances are derived from the number of independent pairs in comments.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from workbench.analysis import northfinding as nfm
from workbench.analysis import northfinding_theory as th
from workbench.calset import Unit
from workbench.earth import EARTH_RATE, earth_rate_ned, rz
from workbench.errors import AnalysisError, RigLimitError
from workbench.grades import load_spec
from workbench.sequence import mount_matrix
from workbench.session import Session, Site, StepRecord
from workbench.sim.noise import NoiseProcess

LAT = np.radians(40.8)
OMEGA_N = EARTH_RATE * np.cos(LAT)
CVG = load_spec("cvg_two_axis")
NOISE = CVG.specs["gyro"].noise
MRAD = 1e-3


def _body_rate(angle: np.ndarray, table_rate: np.ndarray, az0: float, mount: np.ndarray) -> np.ndarray:
    """True body rate (N, 3): C_bn = Rz(az0 + a) @ mount, omega_b = C_bn^T (Omega_ned + (0, 0, r))."""
    w = np.broadcast_to(earth_rate_ned(LAT), (len(angle), 3)).copy()
    w[:, 2] += table_rate
    return (rz((az0 + angle)[:, None]).inv().apply(w)) @ mount  # row form of mount^T (Rz^T w)


def synth_session(angles_deg, dwell_s=60.0, fs=4.0, seed=0, white=NOISE.white, bi=np.zeros(3), rrw=np.zeros(3),
                  bias=(1e-4, -8e-5, 2e-3), drift=(0.0, 0.0, 0.0), az0_deg=102.0, mount="z-down",
                  encoder_offsets_deg=None, carousel=None, lat_deg=40.8, move_s=0.0) -> Session:
    """An in-memory session of static positions (contiguous unless ``move_s``) or one carousel step.

    ``carousel`` = (rate rad/s, laps) replaces the positions. Gyro = truth + bias + drift t + noise.
    ``move_s`` s between positions are not recorded (a table that moves unrecorded); the noise runs on.
    """
    m = mount_matrix(mount)
    proc = NoiseProcess(np.asarray(white, float), np.asarray(bi, float), np.asarray(rrw, float), 1.0 / fs, seed)
    steps, frames, t0 = [], [], 0.0
    if carousel is None:
        plan = [(np.radians(a), 0.0, dwell_s) for a in angles_deg]
    else:
        rate, laps = carousel
        plan = [(0.0, rate, laps * 2 * np.pi / abs(rate))]
    enc = np.zeros(len(plan)) if encoder_offsets_deg is None else np.radians(encoder_offsets_deg)
    for k, (a0, rate, dur) in enumerate(plan):
        if k and move_s:
            proc.generate(int(round(move_s * fs)))
            t0 += move_s
        n = int(round(dur * fs))
        t = t0 + np.arange(n) / fs
        ang = a0 + rate * (t - t0)
        gyro = _body_rate(ang, np.full(n, rate), np.radians(az0_deg), m) + np.asarray(bias) \
            + np.asarray(drift) * t[:, None] + proc.generate(n)
        acc = np.broadcast_to(m.T @ np.array([0.0, 0.0, -9.8]), (n, 3))
        frames.append(pd.DataFrame({"t": t, "step": k, "gx": gyro[:, 0], "gy": gyro[:, 1], "gz": gyro[:, 2],
                                    "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2],
                                    "table_angle": np.mod(ang + enc[k], 2 * np.pi), "table_rate": rate}))
        steps.append(StepRecord(k, "static" if rate == 0 else "carousel", t0, t[-1], m, float(a0), float(rate)))
        t0 = t[-1] + 1.0 / fs
    return Session("synth", Unit("synth-1", ""), Site(lat_deg, table_zero_azimuth_deg=az0_deg), fs, "test", steps,
                   pd.concat(frames, ignore_index=True))


def maytag_angles(pairs: int, offset_deg: float = 0.0, ordering: str = "ABAB") -> list[float]:
    """Table angles of a maytag sequence (A = offset, B = offset + 180°)."""
    pattern = [0, 180] if ordering == "ABAB" else [0, 180, 180, 0]
    return [offset_deg + pattern[k % len(pattern)] for k in range(2 * pairs)]


# -- closed forms -------------------------------------------------------------------------

@pytest.mark.parametrize("psi_deg", [-170.0, -30.0, 0.0, 55.0, 102.0, 179.0])
def test_maytag_azimuth_eq_4_6_noise_free(psi_deg):
    psi = np.radians(psi_deg)
    home = OMEGA_N * np.array([np.cos(psi), -np.sin(psi)]) + [3e-4, -2e-4]  # eq. 4.1, 4.4 + biases
    flipped = -OMEGA_N * np.array([np.cos(psi), -np.sin(psi)]) + [3e-4, -2e-4]  # eq. 4.2, 4.5
    assert nfm.maytag_azimuth(home, flipped) == pytest.approx(nfm.angle_diff(psi, 0.0), abs=1e-12)
    # z-up mount: y points 90° counter-clockwise of x, the y difference changes sign
    home_up = OMEGA_N * np.array([np.cos(psi), np.sin(psi)])
    assert nfm.maytag_azimuth(home_up, -home_up, y_clockwise=False) == pytest.approx(nfm.angle_diff(psi, 0), abs=1e-12)


def test_maytag_one_axis_eq_4_3_is_ambiguous():
    psi = np.radians(102.0)
    m1, m2 = OMEGA_N * np.cos(psi) + 1e-4, -OMEGA_N * np.cos(psi) + 1e-4
    cands = nfm.maytag_azimuth_one_axis(m1, m2, LAT)
    assert cands[0] == pytest.approx(psi, abs=1e-12) and cands[1] == pytest.approx(-psi, abs=1e-12)
    # the ambiguity: both candidates explain the pair (eq. 4.1-4.2: (m1 - m2) / 2 = Omega_N cos(azimuth))
    for c in cands:
        assert OMEGA_N * np.cos(c) == pytest.approx((m1 - m2) / 2, abs=1e-15)


def test_harmonic_fit_of_one_pair_equals_eq_4_6():
    """Least squares of b + sinusoid over two positions 180° apart is eq. 4.6 exactly."""
    s = synth_session(maytag_angles(1), seed=3)
    obs = nfm.static_observations(s, settle_s=2.0)
    geom = nfm.AxisGeometry.from_mount(np.eye(3), np.radians(1.0))
    fit = nfm.fit_harmonic(obs, geom, LAT)
    eq46 = nfm.maytag_azimuth(obs.rate[0, :2], obs.rate[1, :2])
    assert fit.azimuth == pytest.approx(eq46, abs=1e-12)


@pytest.mark.parametrize("mount", ["z-down", "z-up", [[0, -1, 0], [1, 0, 0], [0, 0, 1]]])
def test_noise_free_azimuth_any_level_mount(mount):
    """Azimuth of body x at the table's zero = table zero azimuth + heading of body x in the table."""
    s = synth_session(maytag_angles(2, 30.0), white=np.zeros(3), mount=mount, az0_deg=-40.0)
    nf = nfm.find_north(s, "maytagging")
    assert nf.azimuth_error == pytest.approx(0.0, abs=1e-9)
    assert nf.earth_rate_amplitude == pytest.approx(OMEGA_N, rel=1e-9)
    m = mount_matrix(mount)
    assert nf.true_azimuth == pytest.approx(nfm.angle_diff(np.radians(-40.0) + np.arctan2(m[1, 0], m[0, 0]), 0))


def test_one_level_axis_reports_the_ambiguity():
    mount = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]  # body x level, body y down the table axis (vertical)
    s = synth_session(maytag_angles(3), white=np.zeros(3), mount=mount, az0_deg=60.0)
    nf = nfm.find_north(s, "maytagging", axes=(0, 1))  # z (level here) is not a sensing axis
    assert nf.ambiguous and any("ambiguity" in w for w in nf.warnings)
    truth = np.radians(60.0)
    assert min(abs(nfm.angle_diff(nf.azimuth, truth)), abs(nfm.angle_diff(-nf.azimuth, truth))) < 1e-9
    assert np.isnan(nf.earth_rate_amplitude)  # one axis sees Omega_N cos(psi): amplitude not observed


# -- maytag statistics (thesis sec. 4.4.2, CVG of table 4.1) ------------------------------

def _maytag_runs(seeds, bi, rrw, offsets=None):
    out = []
    for k, seed in enumerate(seeds):
        off = 0.0 if offsets is None else offsets[k]
        s = synth_session(maytag_angles(40, off), fs=10.0 if np.any(bi) else 4.0, seed=seed, bi=bi, rrw=rrw)
        out.append(nfm.find_north(s, "maytagging", grade=CVG))
    return out


def test_maytag_white_noise_matches_arw_theory():
    runs = _maytag_runs(range(10), np.zeros(3), np.zeros(3))
    dev = np.concatenate([nfm.angle_diff(r.unit_azimuth, r.true_azimuth) for r in runs])
    theory = runs[0].theory["arw_unit_sigma"]  # at 102°: ~2.6 mrad for 58 s averages
    assert theory == pytest.approx(2.6 * MRAD, rel=0.05)
    # 400 independent pairs: a std is estimated to 1/sqrt(2*400) = 3.5 %; 15 % is > 4 sigma
    assert np.std(dev) == pytest.approx(theory, rel=0.15)
    # mean error: each sequence mean has sigma theory/sqrt(40) ~ 0.42 mrad; the RMS over 10 seeds < 1 mrad
    errs = np.array([r.azimuth_error for r in runs])
    assert np.sqrt(np.mean(errs**2)) < 1.0 * MRAD
    # reported 1-sigma of the mean is the pair std / sqrt(40): within 30 % of theory / sqrt(40) (40 pairs: 11 %)
    for r in runs:
        assert r.azimuth_sigma == pytest.approx(theory / np.sqrt(40), rel=0.35)


def test_maytag_bias_instability_matches_allan_theory_and_thesis_repeatability():
    # thesis: 4 sequences at the home position, 3 started 90° from it
    runs = _maytag_runs(range(100, 107), NOISE.bias_instability, NOISE.rrw, [0, 0, 0, 0, 90, 90, 90])
    dev = np.concatenate([nfm.angle_diff(r.unit_azimuth, r.true_azimuth) for r in runs])
    # theory per pair from the grade's ADEV at 58 s (IEEE 952); the sequences at 90° weight x and y differently
    theory = np.sqrt(np.mean([r.theory["allan_unit_sigma"] ** 2 for r in runs]))
    # 280 pairs: std known to ~4.2 %; the flicker model's ADEV is flat only to +-5 %: 25 % is wide enough
    assert np.std(dev) == pytest.approx(theory, rel=0.25)
    assert np.all([r.theory["allan_unit_sigma"] > r.theory["arw_unit_sigma"] for r in runs])
    # thesis repeatability: max distance of a sequence mean from the mean of all sequences (0.75-2.4 mrad);
    # expected sigma of a mean ~ theory/sqrt(40) ~ 0.7 mrad, so the max over 7 lies in that span
    means = np.array([nfm.angle_diff(r.azimuth, r.true_azimuth) for r in runs])
    rep, _ = nfm.repeatability(means)
    assert 0.5 * MRAD < rep < 2.4 * MRAD
    table = nfm.sequence_table(runs)
    assert [row["sequence"] for row in table] == [str(i) for i in range(1, 8)]
    assert max(abs(row["distance_mrad"] - 0) for row in table) > 0


def test_maytag_theory_counts_the_dead_time_of_the_turn():
    """With 120 s between positions the pair's two 58-s averages start 180 s apart: flicker and random walk
    decorrelate over the gap, and the per-pair std follows the Allan variance with that dead time (1.27-1.30x
    the adjacent-average theory for this grade). 280 pairs: std known to ~4.2 %; 12 % is ~3 sigma."""
    runs, adjacent = [], []
    adev = th.adev_model(58.0, NOISE.white, NOISE.bias_instability, NOISE.rrw)
    for k, seed in enumerate(range(300, 307)):
        offset = 90.0 * (k >= 4)
        s = synth_session(maytag_angles(40, offset), fs=10.0, seed=seed, bi=NOISE.bias_instability,
                          rrw=NOISE.rrw, move_s=120.0)
        runs.append(nfm.find_north(s, "maytagging", grade=CVG))
        adjacent.append(th.pair_azimuth_sigma(adev[0], LAT, adev[1], np.radians(102.0 + offset)))
    assert all(r.theory["spacing"] == pytest.approx(180.0, abs=0.2) for r in runs)
    dev = np.concatenate([nfm.angle_diff(r.unit_azimuth, r.true_azimuth) for r in runs])
    theory = np.sqrt(np.mean([r.theory["allan_unit_sigma"] ** 2 for r in runs]))
    assert np.std(dev) == pytest.approx(theory, rel=0.12)
    assert np.std(dev) > 1.12 * np.sqrt(np.mean(np.square(adjacent)))  # the adjacent theory misses it


def test_theory_from_the_data_when_no_grade_is_known():
    """Without a grade the Allan theory is the session's own overlapping ADEV at the dwell; ARW is not observed."""
    s = synth_session(maytag_angles(40), fs=4.0, seed=9)
    nf = nfm.find_north(s, "maytagging")
    assert nf.theory["source"].startswith("data")
    assert np.isnan(nf.theory["arw_unit_sigma"])
    res, _ = nfm.to_result(nf)
    assert res["theory"]["arw_pair_sigma_mrad"] is None
    # white noise: ADEV(58 s) = N / sqrt(58); ~40 min of data, ~40 averages: ADEV known to ~15 %, 40 %
    ref = th.pair_azimuth_sigma(NOISE.white[0] / np.sqrt(58), LAT, NOISE.white[1] / np.sqrt(58), np.radians(102))
    assert nf.theory["allan_unit_sigma"] == pytest.approx(ref, rel=0.4)


def test_abba_ordering_cancels_a_linear_drift():
    """ABBA pairs (A,B),(B,A) see the drift with opposite signs; their mean cancels it (ABAB does not)."""
    drift = (4e-9, -2e-9, 0.0)  # rad/s/s: x changes by 2.4e-7 rad/s per 60 s dwell -> ~2 mrad per ABAB pair
    errs = {}
    for ordering in ("ABAB", "ABBA"):
        s = synth_session(maytag_angles(20, ordering=ordering), white=np.zeros(3), drift=drift)
        errs[ordering] = nfm.find_north(s, "maytagging").azimuth_error
    assert abs(errs["ABAB"]) > 1 * MRAD
    assert abs(errs["ABBA"]) < 0.01 * abs(errs["ABAB"])  # what is left is second order (atan2 curvature)


def test_sliding_pairs_an_azimuth_every_dwell():
    """Thesis sec. 4.4.2: 80 azimuths from 40 ABAB pairs, (A1,B1), (B1,A2), ...: the per-pair sigma of
    the disjoint pairs, a linear drift alternating in sign (cancelled in the mean), 1-sigma from rows // 2."""
    runs = [nfm.find_north(synth_session(maytag_angles(40), fs=4.0, seed=seed), "maytagging", grade=CVG,
                           pairs="sliding") for seed in range(10)]
    assert all(len(r.unit_azimuth) == 79 for r in runs)
    dev = np.concatenate([nfm.angle_diff(r.unit_azimuth, r.true_azimuth) for r in runs])
    # 790 azimuths, neighbours correlated 0.5 (a shared dwell): ~400 independent, std known to ~3.5 %; 15 %
    assert np.std(dev) == pytest.approx(runs[0].theory["arw_unit_sigma"], rel=0.15)
    for r in runs:  # 40 independent pairs, not 79
        assert r.azimuth_sigma == pytest.approx(np.std(nfm.angle_diff(r.unit_azimuth, r.azimuth), ddof=1) / np.sqrt(40))
    drift = (4e-9, -2e-9, 0.0)  # ~2 mrad per disjoint pair, as the ABBA test
    s = synth_session(maytag_angles(20), white=np.zeros(3), drift=drift)
    disjoint, sliding = (nfm.find_north(s, "maytagging", pairs=p) for p in ("disjoint", "sliding"))
    # 39 sliding pairs alternate +e, -e, ...: one e is left in the mean, 1/39 = 2.6 % of the disjoint error
    assert abs(disjoint.azimuth_error) > 1 * MRAD
    assert abs(sliding.azimuth_error) < 0.05 * abs(disjoint.azimuth_error)
    assert np.std(sliding.unit_azimuth) == pytest.approx(abs(disjoint.azimuth_error), rel=0.05)
    with pytest.raises(AnalysisError, match="pairs 'overlapping' is not one of disjoint, sliding"):
        nfm.find_north(s, "maytagging", pairs="overlapping")


# -- carousel and multi-position ----------------------------------------------------------

def test_carousel_error_shrinks_with_laps_as_theory_says():
    rate = np.radians(10.0)
    rms = {}
    for laps in (2, 8):
        errs, theory = [], None
        for seed in range(20):
            s = synth_session(None, fs=10.0, seed=seed, carousel=(rate, laps))
            nf = nfm.find_north(s, "carousel", settle_s=0.0, grade=CVG)
            errs.append(nf.azimuth_error)
            theory = th.harmonic_sigma(NOISE.white[:2], 1, LAT) / np.sqrt(laps * 2 * np.pi / rate)
        rms[laps] = np.sqrt(np.mean(np.square(errs)))
        # 20 seeds: an RMS is known to 1/sqrt(40) = 16 %; 40 % is 2.5 sigma
        assert rms[laps] == pytest.approx(theory, rel=0.4)
    assert rms[2] / rms[8] == pytest.approx(2.0, rel=0.45)  # sqrt(8 / 2), each ratio term 16 %


def test_carousel_constant_bias_and_linear_drift_do_not_bias_the_azimuth():
    rate = np.radians(10.0)
    errs, sig = [], []
    for seed in range(10):
        s = synth_session(None, fs=10.0, seed=seed, carousel=(rate, 4), bias=(1.5e-4, -1.5e-4, 2e-3),
                          drift=(3e-9, -2e-9, 0.0))  # 30 °/h bias, ~0.6 °/h/min drift
        nf = nfm.find_north(s, "carousel", settle_s=0.0)
        errs.append(nf.azimuth_error)
        sig.append(nf.azimuth_sigma)
        assert nf.fit.drift[0] == pytest.approx(3e-9, abs=5 * nf.fit.drift_sigma[0])
    # mean of 10 errors has sigma rms(sigma)/sqrt(10): a bias would show beyond 4 of those
    assert abs(np.mean(errs)) < 4 * np.sqrt(np.mean(np.square(sig))) / np.sqrt(10)


def test_multiposition_earth_rate_sweep_amplitude_and_turns():
    s = synth_session([10.0 * k for k in range(72)], dwell_s=30.0, seed=5, drift=(1e-10, 0, 0))
    nf = nfm.find_north(s, "multiposition", grade=CVG)
    assert nf.units == "turn" and len(nf.unit_azimuth) == 2
    # amplitude sigma: 144 rows x 2 axes of ~0.04 °/h position noise -> ~5e-9 rad/s; 5 sigma
    assert nf.earth_rate_amplitude == pytest.approx(OMEGA_N, abs=5 * nf.earth_rate_amplitude_sigma)
    assert abs(nf.azimuth_error) < 5 * nf.fit.azimuth_sigma


# -- redundant configuration (sec. 4.4.3) -------------------------------------------------

def test_redundant_eight_pairings_and_repeatability_table():
    runs = []
    for seed in range(5):
        s = synth_session([45.0 * k for k in range(80)], fs=4.0, seed=200 + seed)
        runs.append(nfm.find_north(s, "redundant", positions_per_turn=8, grade=CVG))
    d = runs[0].detail
    assert d.pairings == ("0-45", "45-90", "90-135", "135-180", "180-225", "225-270", "270-315", "315-0")
    assert d.azimuth.shape == (10, 8)
    dev = np.concatenate([nfm.angle_diff(r.detail.azimuth.ravel(), r.true_azimuth) for r in runs])
    # white noise, bias removed by the turn mean: each estimate has the pair sigma of the mean noise
    # (four axes 45° apart: var(c) = var(s) = sigma^2/2); 400 estimates (correlated within a turn): 15 %
    theory = runs[0].theory["arw_unit_sigma"]
    assert np.std(dev) == pytest.approx(theory, rel=0.15)
    table = nfm.pairing_table(runs)
    assert len(table) == 8 and all(row["repeatability_mrad"] > 0 for row in table)
    # the max distance of 5 session means (10 estimates each) stays within ~3 sigma/sqrt(10)
    assert max(row["repeatability_mrad"] for row in table) < 3.5 * theory / np.sqrt(10) / MRAD
    # the labels are the encoder's whole degrees: 314.996° and 359.996° read as 315° and 0°
    s = synth_session([45.0 * k for k in range(16)], fs=4.0, seed=7, encoder_offsets_deg=[-0.004] * 16)
    assert nfm.find_north(s, "redundant", positions_per_turn=8).detail.pairings == d.pairings


def test_redundant_spread_over_turns_follows_the_noise_model_with_the_bias_wander():
    """Flicker + random walk, the bias removed as the session mean: each pairing's std over the 10 turns and the
    error of its session mean follow the propagated noise (northfinding_spread), well above the known-bias floor.
    16 sessions x 8 pairings x 9 dof, neighbouring pairings sharing a position (~400 independent): the pooled
    rms std is known to ~4 %, 12 % is 3 sigma; the session means (~40 independent) to ~11 %: 35 %."""
    std, theory, err, sigma = [], [], [], []
    for seed in range(16):
        s = synth_session([45.0 * k for k in range(80)], fs=10.0, seed=600 + seed, bi=NOISE.bias_instability,
                          rrw=NOISE.rrw, move_s=6.0)
        nf = nfm.find_north(s, "redundant", grade=CVG)
        spread = nf.theory["pairing_spread"]
        std.append(nf.detail.std)
        theory.append(spread.turn_std)
        err.append(nfm.angle_diff(nf.detail.mean, nf.true_azimuth))
        sigma.append(spread.mean_sigma)
    rms = lambda x: float(np.sqrt(np.mean(np.square(x))))  # noqa: E731
    assert rms(std) == pytest.approx(rms(theory), rel=0.12)
    assert rms(err) == pytest.approx(rms(sigma), rel=0.35)
    assert rms(theory) > 1.8 * nf.theory["allan_unit_sigma"]  # the bias wander, not the floor, dominates
    res, summary = nfm.to_result(nf)
    row = res["redundant"]["pairings"][0]
    assert row["theory_std_mrad"] == pytest.approx(spread.turn_std[0] * 1e3)
    assert any("expected from the noise model with the bias wander" in line for line in summary)


def test_fit_harmonic_stays_unweighted_with_one_residual_per_axis():
    """Two positions, the bias given: four readings, two unknowns; per-axis weights from one residual each would
    only add noise: the estimate equals the plain least squares."""
    from workbench.analysis.northfinding_fit import harmonic_design

    s = synth_session([0.0, 45.0], seed=3)
    obs = nfm.static_observations(s, 2.0)
    geom = nfm.AxisGeometry.from_mount(s.step(0).mount, np.radians(1.0))
    bias = np.array([1e-4, -8e-5, 2e-3])
    got = nfm.fit_harmonic(obs, geom, LAT, bias=bias).azimuth
    a = np.vstack([harmonic_design(obs, geom, i) for i in (0, 1)])
    y = (obs.rate - bias)[:, :2].T.ravel()  # axis-major, as the design
    c, sn = np.linalg.lstsq(a, y, rcond=None)[0]
    assert got == pytest.approx(np.arctan2(sn, c), abs=1e-12)


# -- bad input ----------------------------------------------------------------------------

def test_tilted_axes_are_an_error_naming_the_step():
    s = synth_session(maytag_angles(2), mount="x-up")
    with pytest.raises(AnalysisError, match=r"step 0 mount: body x is tilted 90"):
        nfm.find_north(s, "maytagging")
    tilted = np.asarray(rz(0.0).as_matrix()) @ np.asarray(
        __import__("scipy.spatial.transform", fromlist=["Rotation"]).Rotation.from_euler("x", 20, degrees=True)
        .as_matrix())
    with pytest.raises(AnalysisError, match=r"gyro axis y is tilted 20"):
        nfm.find_north(synth_session(maytag_angles(2), mount=tilted), "maytagging")


def test_index_that_is_not_180_by_the_encoder_is_an_error():
    s = synth_session(maytag_angles(3), encoder_offsets_deg=[0, 0, 0, 0.3, 0, 0])
    with pytest.raises(AnalysisError, match=r"steps 2 -> 3: the index is 180.3000° by the encoder, not 180°"):
        nfm.find_north(s, "maytagging")


def test_dwell_shorter_than_settling_is_an_error():
    s = synth_session(maytag_angles(2), dwell_s=3.0)
    with pytest.raises(AnalysisError,
                       match=r"step 0 \(static\): static dwell 2.75 s is not longer than the settling time 5 s"):
        nfm.find_north(s, "maytagging", settle_s=5.0)
    import procedures.maytagging as may

    with pytest.raises(RigLimitError, match="dwell_s 2 s is not longer than the settling time"):
        may.sequence(CVG, dwell_s=2.0, settle_s=2.0)


def test_latitude_near_a_pole_is_an_error():
    s = synth_session(maytag_angles(2), lat_deg=89.5)
    with pytest.raises(AnalysisError, match=r"latitude 89.500° is within 1° of a pole"):
        nfm.find_north(s, "maytagging")


def test_wrong_latitude_shows_in_the_earth_rate_amplitude():
    s = synth_session(maytag_angles(10), white=np.zeros(3))
    wrong = Session(s.id, s.unit, Site(20.0, table_zero_azimuth_deg=102.0), s.sample_rate_hz, s.procedure,
                    s.steps, s.samples)
    nf = nfm.find_north(wrong, "maytagging")
    assert any("wrong site latitude" in w for w in nf.warnings)
    assert abs(nf.azimuth_error) < 1e-9  # eq. 4.6 needs no latitude


# -- procedures through the simulator -----------------------------------------------------

def test_maytagging_procedure_through_the_simulator():
    import procedures.maytagging as may
    from workbench.procedure import result_json
    from workbench.jobs import simulate

    seq = may.sequence(CVG, count=6, ordering="ABBA", start_offset_deg=90.0)
    session, truth = simulate(seq, CVG, seed=11)
    res = may.analyze(session)
    doc = json.loads(result_json(res), parse_constant=lambda c: pytest.fail(f"{c} in result.json"))
    for key in ("azimuth_deg", "azimuth_sigma_mrad", "pair_azimuths_deg", "pair_std_mrad", "gyro_bias",
                "earth_rate_amplitude", "azimuth_error_mrad"):
        assert key in doc
    assert set(doc["theory"]) >= {"arw_pair_sigma_mrad", "allan_pair_sigma_mrad"}
    assert len(doc["pair_azimuths_deg"]) == 6 and res.calibration is None
    # 6 pairs of ~4.5 mrad (grade ADEV theory): the mean within 4 sigma/sqrt(6) ~ 7 mrad
    assert abs(doc["azimuth_error_mrad"]) < 4 * doc["theory"]["allan_pair_sigma_mrad"] / np.sqrt(6)
    # scale factor 200 ppm (1 sigma) and the fit's noise: amplitude within 1 %
    assert doc["earth_rate_amplitude"] == pytest.approx(OMEGA_N, rel=0.01)
    assert set(may.figures(res)) == {"earth_rate", "azimuth"}


def test_carousel_and_earth_rate_procedures_through_the_simulator():
    import procedures.carousel as car
    import procedures.earth_rate as er
    from workbench.jobs import simulate

    s, _ = simulate(car.sequence(CVG, rate_deg_s=30.0, laps=3), CVG, seed=4)
    res = car.analyze(s)
    assert res.result["units"] == "lap" and len(res.result["pair_azimuths_deg"]) == 3
    # 36 s of CVG data: ARW theory ~ 1.3 mrad; 5 sigma plus the 0.2 mrad fixture error
    assert abs(res.result["azimuth_error_mrad"]) < 5 * res.result["theory"]["arw_pair_sigma_mrad"] / np.sqrt(3) + 0.5
    s, _ = simulate(er.sequence(CVG, dwell_s=10.0, step_deg=45.0, turns=1), CVG, seed=5)
    res = er.analyze(s)
    assert res.result["earth_rate_amplitude"] == pytest.approx(OMEGA_N, rel=0.03)


def test_redundant_procedure_through_the_simulator():
    import procedures.redundant as red
    from workbench.jobs import simulate

    s, _ = simulate(red.sequence(CVG, dwell_s=10.0, turns=2), CVG, seed=6)
    res = red.analyze(s)
    rows = res.result["redundant"]["pairings"]
    assert [r["pairing_deg"] for r in rows][:2] == ["0-45", "45-90"] and all(r["n"] == 2 for r in rows)
    assert len(res.result["pair_azimuths_deg"]) == 16
    # 16 estimates of ~ARW theory at 8 s (~6 mrad) plus bias wander: mean within 15 mrad (~8 sigma/sqrt(16))
    assert abs(res.result["azimuth_error_mrad"]) < 15.0
    assert set(red.figures(res)) == {"earth_rate", "azimuth", "pairings"}


def test_applies_only_to_grades_that_resolve_earth_rate():
    import procedures.maytagging as may

    assert may.applies(CVG) and may.applies(load_spec("navigation_grade"))
    assert not may.applies(load_spec("industrial_mems")) and not may.applies(load_spec("consumer_9axis"))


def test_discard_s_warm_up_is_held_and_left_out():
    # thesis table 4.2, sequences 8-11: "the measurements are extracted one hour after the starting".
    # The sequence holds the first position discard_s first (labelled warm-up); the analysis leaves
    # out every step that starts earlier. Given to the analysis alone, the early positions go.
    import procedures.maytagging as may
    import procedures.redundant as red
    from workbench.errors import AnalysisError
    from workbench.jobs import simulate

    seq = may.sequence(CVG, count=2, dwell_s=20.0, discard_s=45.0)
    s, _ = simulate(seq, CVG, seed=12)
    first = s.steps[0]
    assert first.label == "warm-up" and first.t_end - first.t_start == pytest.approx(45.0, abs=0.02)
    res = may.analyze(s)
    assert len(res.result["pair_azimuths_deg"]) == 2  # the warm-up hold is not a position
    # 2 pairs of 18 s: within 4 sigma / sqrt(2) of the grade-ADEV pair theory (as the test above)
    assert abs(res.result["azimuth_error_mrad"]) < 4 * res.result["theory"]["allan_pair_sigma_mrad"] / np.sqrt(2)
    # the analysis' default is the recorded warm-up; the warm-up hold counted (discard_s 0) is one more static step
    assert len(nfm.static_observations(s, 2.0)) == 5 and "warm-up" not in res.summary[0]

    s, _ = simulate(red.sequence(CVG, dwell_s=10.0, turns=2), CVG, seed=6)
    one_turn = s.steps[8].t_start - float(s.samples["t"].iloc[0]) - 1.0  # s: the second turn starts after it
    rows = red.analyze(s, discard_s=one_turn).result["redundant"]["pairings"]
    assert all(r["n"] == 1 for r in rows)  # one turn left of the two
    with pytest.raises(AnalysisError, match="no step starts after the 10000 s discarded"):
        red.analyze(s, discard_s=1e4)
