"""Tests of workbench.analysis.northfinding_theory against the thesis's figures, Monte Carlo
references and the simulator's noise model."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.analysis import northfinding_theory as th
from workbench.analysis.allan import deviation
from workbench.earth import EARTH_RATE
from workbench.errors import AnalysisError
from workbench.grades import load_spec
from workbench.sim.noise import NoiseProcess
from workbench.units import from_unit, to_unit

LAT = np.radians(40.8)
OMEGA_N = EARTH_RATE * np.cos(LAT)


def test_eq_4_12_requirements_at_naples():
    """Thesis sec. 4.2: at 40.8° and 1 mrad, 0.023 °/h bias stability and, with 100 °/h bias, ~230 ppm."""
    db = th.bias_stability_requirement(1e-3, LAT)
    assert round(float(to_unit(db, "deg/h")), 3) == 0.023
    eps = th.scale_stability_requirement(1e-3, LAT, from_unit(100.0, "deg/h"))
    assert to_unit(eps, "ppm") == pytest.approx(230.0, rel=0.02)


def test_eq_4_11_against_the_exact_one_axis_maytag():
    """Eq. 4.11 is the first-order error of eq. 4.3 with a bias and a scale-factor shift (eq. 4.7-4.10)."""
    psi, b1 = np.radians(80.0), from_unit(30.0, "deg/h")
    db, es = from_unit(0.02, "deg/h"), 50e-6
    s1 = 1.0
    m1 = (OMEGA_N * np.cos(psi) + b1) / s1  # eq. 4.9
    m2 = (-OMEGA_N * np.cos(psi) + b1 + db) / (s1 * (1 + es))  # eq. 4.10 with eq. 4.7, 4.8
    psi_hat = np.arccos(s1 * (m1 - m2) / (2 * OMEGA_N))  # eq. 4.3 (bias assumed common)
    predicted = th.maytag_error(db, es, b1 + db, psi, LAT)
    # psi_hat - psi = -(error in cos psi)/sin psi: eq. 4.11 gives it to second order (1e-3 relative)
    assert psi_hat - psi == pytest.approx(predicted, rel=5e-3)
    # east-pointing gyro and small eps_s: eq. 4.11 reduces to eq. 4.12
    assert th.maytag_error(db, es, b1, np.pi / 2, LAT) == pytest.approx((db - es * b1) / (2 * OMEGA_N), rel=1e-4)


def test_pair_sigma_of_the_cvg_arw():
    """Issue figure: ARW 0.0055 °/√h, 60 s dwell, 40.8° -> about 2.65 mrad per pair."""
    arw = from_unit(0.0055, "deg/sqrt(h)")
    assert th.pair_azimuth_sigma(arw / np.sqrt(60.0), LAT, arw / np.sqrt(60.0), 1.0) == pytest.approx(2.65e-3, rel=0.01)


def test_pair_sigma_azimuth_weighting_by_monte_carlo():
    """Linearised eq. 4.6: var = (sin^2 psi sx^2 + cos^2 psi sy^2) / (2 Omega_N^2); 200k draws (std to 0.2 %)."""
    rng = np.random.default_rng(1)
    sx, sy, psi = 3e-7, 1e-7, np.radians(30.0)
    n = 200_000
    m = OMEGA_N * np.array([np.cos(psi), -np.sin(psi)])
    home = m + rng.normal(0, 1, (n, 2)) * [sx, sy]
    flipped = -m + rng.normal(0, 1, (n, 2)) * [sx, sy]
    d = (home - flipped) / 2
    est = np.arctan2(-d[:, 1], d[:, 0])
    assert np.std(est - psi) == pytest.approx(th.pair_azimuth_sigma(sx, LAT, sy, psi), rel=0.02)
    one = np.arccos(np.clip(d[:, 0] / OMEGA_N, -1, 1))
    assert np.std(one - psi) == pytest.approx(th.pair_azimuth_sigma(sx, LAT, None, psi), rel=0.02)


def test_harmonic_sigma_by_monte_carlo():
    """Eight positions round a turn, two axes, bias fitted: least squares scatter vs the closed form."""
    rng = np.random.default_rng(2)
    a = np.radians(np.arange(0, 360, 45.0))
    sig = np.array([2e-7, 1e-7])
    psi = np.radians(102.0)
    design = []
    for alpha in (0.0, np.pi / 2):
        blk = np.zeros((8, 4))
        blk[:, 0], blk[:, 1] = np.cos(alpha + a), -np.sin(alpha + a)
        blk[:, 2 + int(alpha > 0)] = 1.0
        design.append(blk)
    x = np.vstack(design)
    truth = np.concatenate([OMEGA_N * np.cos(psi + al + a) for al in (0.0, np.pi / 2)])
    w = np.repeat(1 / sig, 8)
    est = []
    for _ in range(5000):
        y = truth + rng.normal(0, 1, 16) * np.repeat(sig, 8)
        p = np.linalg.lstsq(x * w[:, None], y * w, rcond=None)[0]
        est.append(np.arctan2(p[1], p[0]))
    # 5000 draws: std to 1 %; 4 %
    assert np.std(np.array(est) - psi) == pytest.approx(th.harmonic_sigma(sig, 8, LAT), rel=0.04)


def test_adev_model_matches_the_simulated_cvg_noise():
    """IEEE 952 closed form vs the overlapping ADEV at 58 s of the simulator's CVG noise (6 h at 10 Hz)."""
    nz = load_spec("cvg_two_axis").specs["gyro"].noise
    y = NoiseProcess(nz.white[:2], nz.bias_instability[:2], nz.rrw[:2], 0.1, 7).generate(216_000)
    measured = deviation(y, 10.0, "oadev", taus=np.array([58.0])).dev[0]
    model = th.adev_model(58.0, nz.white[:2], nz.bias_instability[:2], nz.rrw[:2])
    # ~370 independent 58 s averages: ADEV known to ~1/sqrt(370)... with overlap and flicker ~8 %; 25 %
    np.testing.assert_allclose(measured, model, rtol=0.25)


def test_gyrocompass_accuracy_of_paper_001_eq_48():
    """Paper 001 table 3-1 grades at 40.8°: 1 mg / 1 °/h -> ~88 mrad; 0.05 mg / 0.05 °/h -> ~4.4 mrad."""
    g = 9.80665
    tac = th.gyrocompass_sigma(from_unit(1.0, "mg"), from_unit(1.0, "deg/h"), LAT, g)
    nav = th.gyrocompass_sigma(from_unit(0.05, "mg"), from_unit(0.05, "deg/h"), LAT, g)
    # hand: 1 °/h / (15.041 °/h cos 40.8°) = 0.08780 rad, (+) 1e-3 rad -> 0.08781
    assert tac == pytest.approx(0.08781, rel=1e-3)
    assert nav == pytest.approx(np.hypot(5e-5, 0.004390), rel=1e-3)


def test_latitude_within_a_degree_of_a_pole_is_an_error():
    with pytest.raises(AnalysisError, match="within 1° of a pole"):
        th.horizontal_rate(np.radians(-89.2))
    assert th.horizontal_rate(np.radians(88.9)) > 0
