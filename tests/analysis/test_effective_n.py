"""Effective sample size, misfit factor and moving-block bootstrap against closed forms and coverage."""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from workbench.analysis.effective_n import (block_jackknife, block_refits, ess, ess_scale, honest_covariance, misfit_scale,
                                            tau_int)


def _ar1(phi: float, n: int, c: int, seed: int) -> np.ndarray:
    """AR(1) x_k = phi x_(k-1) + e_k, unit marginal variance; tau_int = (1 + phi) / (1 - phi)."""
    e = np.random.default_rng(seed).standard_normal((n, c)) * np.sqrt(1 - phi**2)
    return lfilter([1.0], [1.0, -phi], e, axis=0)


def test_tau_int_of_ar1_matches_the_closed_form():
    # Sokal (1996) eq. 3.19: var(tau_hat) ~ 2 (2M + 1) / N tau^2, window M ~ 5 tau; pooled over 3 columns
    # divides the variance by 3. phi = 0.9: tau = 19, M ~ 95, N = 60000: relative sigma
    # sqrt(2 * 191 / 60000 / 3) = 4.6 %; 4 sigma (plus the window's own truncation bias, ~ exp(-5) < 1 %) = 20 %.
    for phi, tol in ((0.5, 0.20), (0.9, 0.20)):
        tau = (1 + phi) / (1 - phi)
        est = tau_int(_ar1(phi, 60000, 3, 1))
        assert abs(est / tau - 1) < tol, (phi, est, tau)


def test_white_noise_is_left_white():
    # the estimate is kept at 1 unless it exceeds 1 + 2 sqrt(4M/N): a false inflation is a 2.3 % event
    inflated = sum(ess_scale(np.random.default_rng(s).standard_normal((2000, 3))) > 1 for s in range(40))
    assert inflated <= 5  # binomial(40, 0.023): P(> 5) < 1e-3
    x = np.random.default_rng(0).standard_normal(5000)
    assert ess(x) == 5000


def _mean_sigma(x: np.ndarray) -> float:
    """Honest sigma of the mean of ``x`` (N, 1): the mean as a least-squares fit through honest_covariance."""
    r = x - x.mean()
    return float(np.sqrt(honest_covariance(np.array([[float(r.var(ddof=1)) / len(r)]]), r)[0, 0]))


def _moving_block_bootstrap_sd(x: np.ndarray, block: int, n_boot: int, seed: int) -> float:
    """Sigma of the mean of ``x`` (N, 1) from ``n_boot`` moving-block resamples (Kunsch 1989): each joins
    ceil(N / block) blocks of ``block`` consecutive rows from random starts, cut to N rows."""
    n = len(x)
    rng = np.random.default_rng(seed)
    starts = rng.integers(0, n - block + 1, size=(n_boot, -(-n // block)))
    idx = (starts[:, :, None] + np.arange(block)).reshape(n_boot, -1)[:, :n]
    return float(x[idx, 0].mean(axis=1).std())


def test_mean_sigma_covers_gauss_markov_noise_where_the_white_formula_does_not():
    # 400 records of N = 2000 samples: white (unit) + Gauss-Markov (unit variance, phi = 0.98, correlation
    # time 50 samples): rho_k = 0.5 phi^k, tau_int = 1 + phi / (1 - phi) = 50, so std/sqrt(N) is sqrt(50) = 7.1x
    # too small and covers 2 Phi(1 / 7.1) - 1 = 11 %.
    # Binomial tolerance of the 1-sigma coverage 0.683 over 400 records: sigma sqrt(0.683 * 0.317 / 400)
    # = 2.3 %; 3 sigma = 7 %.
    n, phi, seeds = 2000, 0.98, 400
    cover_white = cover_ess = 0
    for s in range(seeds):
        rng = np.random.default_rng(100 + s)
        gm = lfilter([1.0], [1.0, -phi], rng.standard_normal(n) * np.sqrt(1 - phi**2))
        x = (gm + rng.standard_normal(n))[:, None]
        m = abs(float(x.mean()))
        cover_white += m < x.std(ddof=1) / np.sqrt(n)
        cover_ess += m < _mean_sigma(x)
    assert cover_white / seeds < 0.3
    assert abs(cover_ess / seeds - 0.683) < 0.07, cover_ess / seeds


def test_bootstrap_agrees_with_the_effective_sample_size():
    # AR(1) phi = 0.8 (tau 9): sigma of the mean sqrt(tau / N); blocks of 100 >> tau. The bootstrap's
    # own relative error with 400 resamples is 1 / sqrt(2 * 400) = 3.5 %, the block bias ~ tau / block
    # = 9 %: 25 % covers both at 2 sigma.
    x = _ar1(0.8, 20000, 1, 3)
    boot = _moving_block_bootstrap_sd(x, block=100, n_boot=400, seed=1)
    assert abs(boot / _mean_sigma(x) - 1) < 0.25
    assert abs(_mean_sigma(x) / np.sqrt(9.0 / 20000) - 1) < 0.25


def test_misfit_and_combined_scale():
    assert misfit_scale(50.0, 50) == 1.0 and misfit_scale(10.0, 40) == 1.0
    assert np.isclose(misfit_scale(200.0, 50), 2.0)
    assert misfit_scale(5.0, 0) == 1.0
    # white residuals twice the assumed sigma: the misfit factor is 2, no correlation factor
    r = 2.0 * np.random.default_rng(4).standard_normal((4000, 3))
    chi2 = float(np.sum(r**2))
    assert abs(misfit_scale(chi2, r.size - 10) * ess_scale(r) / 2.0 - 1) < 0.05  # chi2 of 12000 dof: relative sd 0.6 %


def test_honest_covariance_of_a_mean_is_tau_times_the_white_one():
    # the mean as a least-squares fit: J = 1 per point, score = residual: the scale is tau_int of the residuals
    from workbench.analysis.effective_n import honest_covariance

    x = _ar1(0.8, 20000, 1, 5)
    r = x - x.mean()
    cov = np.array([[float(r.var()) / len(r)]])
    tau = tau_int(r)
    assert np.isclose(honest_covariance(cov, r)[0, 0], cov[0, 0] * tau)
    assert np.isclose(honest_covariance(cov, r, np.ones((len(r), 1)))[0, 0], cov[0, 0] * tau)


def test_block_jackknife_of_a_mean_and_the_move_between_blocks():
    """Mean of 20000 white samples (sigma 1): the jackknife sigma over 5 blocks is 1/sqrt(N) within its
    own spread (a variance from 4 degrees of freedom: over 200 records the mean of sigma_J^2 N is 1 within
    4 sqrt(2 / 4 / 200) = 0.2), and the between-block part is small (E[max(0, chi2_4 / 4 - 1)] ~ 0.3 of
    K / N). A mean that steps by 1 half way (blocks 0-1 at 0, 3-4 at 1): the pseudo-values are the block
    means (0, 0, 0.5, 1, 1), variance 0.25, so the between-block sigma is ~0.5 and the jackknife's ~0.22."""
    rng = np.random.default_rng(3)
    n = 20000
    jk2, between2 = [], []
    for _ in range(200):
        x = rng.standard_normal(n)
        full = np.array([x.mean()])
        jk, between = block_jackknife(full, block_refits(lambda keep: np.array([x[keep].mean()]), n, 5),
                                      np.array([1 / np.sqrt(n)]))
        jk2.append(jk[0] ** 2 * n)
        between2.append(between[0] ** 2 * n)
    assert abs(np.mean(jk2) - 1.0) < 0.2
    assert np.mean(between2) < 0.6 * 5
    step = np.r_[np.zeros(n // 2), np.ones(n // 2)] + 0.01 * rng.standard_normal(n)
    refits = block_refits(lambda keep: np.array([step[keep].mean(), np.nan]), n, 5)
    jk, between = block_jackknife(np.array([step.mean(), np.nan]), refits, np.array([0.01 / np.sqrt(n), np.nan]))
    assert abs(between[0] - 0.5) < 0.01 and abs(jk[0] - np.sqrt(0.25 / 5)) < 0.01
    assert np.isnan(jk[1]) and np.isnan(between[1])
