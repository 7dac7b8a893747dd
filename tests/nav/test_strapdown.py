"""Tests of workbench.nav.strapdown against closed forms."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from workbench.earth import earth_rate_ned, gravity_ned
from workbench.nav.strapdown import (BlockPropagator, attitude_errors, coarse_level, from_rph, gain_weight,
                                     sequential_update, skew)

LAT = np.radians(40.8)


def test_propagation_of_an_earth_fixed_unit_stays_put():
    # a body at rest senses only C^T w_ie: with the Earth rate removed the attitude is constant
    c0 = from_rph(0.3, -0.2, 1.0)
    w_b = c0.inv().apply(earth_rate_ned(LAT))
    prop = BlockPropagator(100, 0.01, earth_rate_ned(LAT))
    c = c0.as_matrix()
    for _ in range(600):  # 10 min
        c = prop.propagate(c, np.tile(w_b, (101, 1)))[-1]
    assert np.linalg.norm(Rotation.from_matrix(c @ c0.as_matrix().T).as_rotvec()) < 1e-10


def test_propagation_matches_a_constant_rotation_and_folds_a_correction():
    w = np.array([0.1, -0.3, 0.7])
    prop = BlockPropagator(64, 0.01, np.zeros(3))
    out = prop.propagate(np.eye(3), np.tile(w, (65, 1)))
    expect = Rotation.from_rotvec(np.outer(np.arange(1, 65) * 0.01, w)).as_matrix()
    np.testing.assert_allclose(out, expect, atol=1e-12)
    e = np.array([1e-3, -2e-3, 5e-4])
    c0 = from_rph(0.1, 0.2, 0.3).as_matrix()
    folded = prop.propagate(c0, np.tile(w, (65, 1)), e)[-1]
    direct = prop.propagate(Rotation.from_rotvec(e).as_matrix() @ c0, np.tile(w, (65, 1)))[-1]
    np.testing.assert_allclose(folded, direct, atol=1e-12)


def test_coarse_level_and_attitude_errors():
    c = from_rph(np.radians(12.0), np.radians(-7.0), np.radians(200.0))
    f_b = c.inv().apply(-gravity_ned(LAT))
    roll, pitch = coarse_level(f_b[None, :])
    np.testing.assert_allclose([roll, pitch], np.radians([12.0, -7.0]), atol=1e-12)
    est = from_rph(np.radians(12.1), np.radians(-7.0), np.radians(-159.5))  # heading wraps across ±180°
    np.testing.assert_allclose(attitude_errors(est, c), np.radians([0.1, 0.0, 0.5]), atol=1e-9)
    locked = attitude_errors(from_rph(0, np.radians(89.0), 0), from_rph(0, np.radians(89.5), 0))
    assert np.isnan(locked[0]) and np.isnan(locked[2])


def test_gain_weight_is_continuous_and_bounded():
    assert gain_weight(0.5, 3, 6) == 1.0 and gain_weight(3.0, 3, 6) == 1.0
    assert gain_weight(6.0, 3, 6) == 0.0 and gain_weight(7.0, 3, 6) == 0.0
    assert abs(gain_weight(3.0 + 1e-9, 3, 6) - 1.0) < 1e-8
    assert abs(gain_weight(4.5, 3, 6) - 3 * 1.5 / (4.5 * 3)) < 1e-12


def test_batch_and_sequential_updates_agree():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(6, 6))
    P = a @ a.T + np.eye(6)
    H = rng.normal(size=(3, 6))
    z, r = rng.normal(size=3), np.array([0.5, 1.0, 2.0])
    Pb, xb, _ = sequential_update(P, H, z, r)
    Ps, xs, w = sequential_update(P, H, z, r, scaling=(1e9, 2e9))  # thresholds never reached: plain sequential
    np.testing.assert_allclose(Pb, Ps, atol=1e-10)
    np.testing.assert_allclose(xb, xs, atol=1e-10)
    assert np.all(w == 1.0)


def test_expm_small_matches_scipy():
    # the Van Loan block of a 15-state INS error model over 1 s (norm ~10, scaled and squared) and a
    # random matrix: against scipy's Pade expm, to the 1e-12 a double-precision series gives
    from scipy.linalg import expm

    from workbench.nav.strapdown import expm_small

    rng = np.random.default_rng(3)
    a = rng.normal(0.0, 1.0, (18, 18))
    f = np.zeros((15, 15))
    f[0:3, 3:6] = np.eye(3)
    f[3:6, 6:9] = -skew(np.array([0.0, 0.0, -9.81]))
    for m in (a, f, 0.01 * a):
        np.testing.assert_allclose(expm_small(m), expm(m), rtol=1e-11, atol=1e-12 * np.abs(expm(m)).max())


def test_sequential_update_with_correlated_noise_matches_the_batch_formula():
    """``cross`` = E[δx vᵀ]: the scalar updates equal the batch update of Simon, *Optimal State Estimation*
    sec. 7.1, ``K = (P Hᵀ + M)(H P Hᵀ + H M + Mᵀ Hᵀ + R)⁻¹``, ``P⁺ = P - K (H P + Mᵀ)``; and the posterior is
    the sample covariance of the estimate error over correlated draws (200 000 draws: 1 % on each element's
    scale, 5 sigma of the sampling error allowed)."""
    from workbench.nav.strapdown import sequential_update

    rng = np.random.default_rng(4)
    n, m = 5, 3
    # δx = A w + B u, v = diag(β) w (w, u independent unit normals): independent noises, correlated with δx
    A, B, beta = rng.standard_normal((n, m)), rng.standard_normal((n, n)), rng.uniform(0.5, 2.0, m)
    P, M, R = A @ A.T + B @ B.T, A * beta, np.diag(beta ** 2)
    joint = np.block([[P, M], [M.T, R]])
    H = rng.standard_normal((m, n))
    k = np.linalg.solve(H @ P @ H.T + H @ M + M.T @ H.T + R, (P @ H.T + M).T).T
    p_batch = P - k @ (H @ P + M.T)
    p_seq, _, _ = sequential_update(P, H, np.zeros(m), np.diag(R), cross=M)
    np.testing.assert_allclose(p_seq, p_batch, atol=1e-10 * np.abs(P).max())
    draws = rng.multivariate_normal(np.zeros(n + m), joint, 200_000)
    e, v = draws[:, :n], draws[:, n:]
    resid = e - (e @ H.T + v) @ k.T
    scale = np.sqrt(np.outer(np.diag(p_batch), np.diag(p_batch)))
    assert np.all(np.abs(np.cov(resid.T) - p_batch) < 5 * np.sqrt(2.0 / 200_000) * 2 * scale)
