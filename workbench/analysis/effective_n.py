"""Honest sigmas on correlated data: effective sample size, model misfit, block jackknife.

A least-squares or mean sigma from a white-noise formula (``s / sqrt(N)``) is too small when
the residuals are correlated in time (bias instability, Gauss-Markov drift, a hand-held motion
whose model misfit is smooth in time) or larger than the noise model says (model misfit). Two
factors correct it, each >= 1, and multiply the white-noise sigma:

- :func:`ess_scale` = ``sqrt(N / N_eff)``, ``N_eff = N / tau_int`` with the integrated
  autocorrelation time ``tau_int = 1 + 2 sum_k rho_k`` of the residuals in time order
  (:func:`tau_int`: FFT autocorrelation, Sokal's automatic window ``M >= C * tau_int(M)``, C = 5;
  on white noise the estimate is kept at 1 unless it exceeds two standard errors,
  ``sqrt(4 M / N)``, of its white-noise spread).
- :func:`misfit_scale` = ``sqrt(max(1, chi2 / dof))``: the reduced chi-square.

:func:`honest_covariance` scales a least-squares covariance per parameter by the correlation time
of its score series (a Newey-West sandwich in effective-sample-size form; for a mean, the honest
sigma of the mean of a static record); :func:`tau_int_records` one correlation time from several
records (the static steps of a session); :func:`block_refits` and :func:`block_jackknife` the sigma of a fit's outputs from refits that
each leave out one of K contiguous blocks in time (delete-a-block jackknife, Kunsch 1989 sec. 2)
and how much they move between blocks beyond the noise: they see what a stationary correlation
model cannot, a model misfit or a coefficient that changes along the record (a hand-held record
visits its orientations one stretch after the other).

References: A. Sokal, "Monte Carlo methods in statistical mechanics" (1996), sec. 3 (the
automatic window); H. Kunsch, Ann. Statist. 17 (1989) 1217 (the moving-block bootstrap);
IEEE Std 952 (the flicker floor that a record's own autocorrelation can only partly show). The tests
check :func:`tau_int` against a moving-block bootstrap (Kunsch 1989), which needs no model of the correlation.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

WINDOW_C = 5.0  # Sokal's window constant: sum the autocorrelation up to M >= C * tau_int(M)


def autocorrelation(x: np.ndarray) -> np.ndarray:
    """Sample autocorrelation (N, C) of each column of ``x`` (N,) or (N, C), lags 0..N-1 (FFT, mean removed)."""
    x = np.asarray(x, float)
    x = x[:, None] if x.ndim == 1 else x
    n = len(x)
    d = x - x.mean(axis=0)
    size = 1 << int(np.ceil(np.log2(2 * n)))
    f = np.fft.rfft(d, size, axis=0)
    acov = np.fft.irfft(f * np.conj(f), size, axis=0)[:n] / n
    var = acov[0]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(var > 0, acov / np.where(var > 0, var, 1.0), 0.0)


def tau_int(x: np.ndarray, pooled: bool = True) -> np.ndarray | float:
    """Integrated autocorrelation time (samples, >= 1) of ``x`` (N,) or (N, C) in time order.

    ``pooled``: one value for all columns (their autocorrelations averaged: the components of a
    triad share one noise process type), else one per column. Sokal's automatic window; 1 when
    the estimate is within two white-noise standard errors of 1 (white noise stays white).
    """
    rho = autocorrelation(x)
    if pooled:
        rho = rho.mean(axis=1, keepdims=True)
    out = _windowed(rho, rho.shape[0])
    return float(out[0]) if pooled else out


def tau_int_records(records: list[np.ndarray]) -> np.ndarray:
    """Integrated autocorrelation time (C,) per column, pooled over several records (N_i, C) of one process.

    The records' autocorrelations (each about its own mean: the steps of a session, whose means
    differ) are averaged with weights N_i up to the shortest record's length; the window and the
    white-noise test as :func:`tau_int`, with the total sample count.
    """
    n_min = min(len(r) for r in records)
    weights = np.array([len(r) for r in records], float)
    rho = sum(w * autocorrelation(r)[:n_min] for w, r in zip(weights, records)) / weights.sum()
    return _windowed(rho, int(weights.sum()), n_min)


def _windowed(rho: np.ndarray, n_total: int, n_lags: int | None = None) -> np.ndarray:
    """Sokal-windowed tau_int (C,) of autocorrelations ``rho`` (L, C); 1 where within 2 white standard errors."""
    n = n_lags or rho.shape[0]
    rho = rho[:n]
    out = np.ones(rho.shape[1])
    for c in range(rho.shape[1]):
        taus = 1.0 + 2.0 * np.cumsum(rho[1:, c])
        m = np.arange(1, n)
        ok = np.flatnonzero(m >= WINDOW_C * taus)
        if not len(ok):
            continue  # the window never closes: the record is too short to say
        k = int(ok[0])
        tau, window = float(taus[k]), int(m[k])
        if tau > 1.0 + 2.0 * np.sqrt(4.0 * window / n_total):
            out[c] = tau
    return out


def ess(x: np.ndarray, pooled: bool = True) -> np.ndarray | float:
    """Effective sample size ``N / tau_int`` of ``x`` (N,) or (N, C) in time order."""
    return len(np.asarray(x)) / tau_int(x, pooled)


def ess_scale(residuals: np.ndarray, pooled: bool = True) -> np.ndarray | float:
    """``sqrt(N / N_eff)`` (>= 1): the factor on a white-noise sigma for residuals correlated in time.

    ``residuals`` (N,) or (N, C) in time order (one column per residual component); pooled over
    the columns unless ``pooled=False``.
    """
    return np.sqrt(tau_int(residuals, pooled))


def misfit_scale(chi2: float, dof: float) -> float:
    """``sqrt(max(1, chi2 / dof))``: the factor on a sigma for a reduced chi-square above 1 (1 if dof <= 0)."""
    if dof <= 0 or not np.isfinite(chi2):
        return 1.0
    return float(np.sqrt(max(1.0, chi2 / dof)))








def block_refits(stat: Callable[[np.ndarray], np.ndarray], n: int, blocks: int) -> np.ndarray:
    """``stat`` (P,) refitted ``blocks`` times over ``n`` points in time order, each time without one of
    ``blocks`` contiguous blocks: (K, P). ``stat(keep)`` computes it from the points of a (n,) bool mask."""
    keep = np.ones(n, bool)
    out = []
    for part in np.array_split(np.arange(n), blocks):
        keep[part] = False
        out.append(np.asarray(stat(keep), float))
        keep[part] = True
    return np.array(out)


def block_jackknife(full: np.ndarray, refits: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(jackknife sigma, between-block sigma) (P,) of a statistic from its :func:`block_refits` (K, P).

    ``full`` (P,) the statistic on all points, ``sigma`` (P,) its sigma from a model of the noise
    (e.g. :func:`honest_covariance`). Jackknife: ``sigma_J^2 = (K - 1) / K sum_k (s_k - mean s)^2``.
    Between blocks: the pseudo-values ``K full - (K - 1) s_k`` estimate the statistic on each block
    alone, each with variance ``K sigma^2`` if the statistic is the same along the record; their
    variance beyond that (``max(0, var - K sigma^2)``) is how much it moves from one stretch of the
    record to the next (a random effect, as the Paule-Mandel between-step variance of the static fits).
    Each block must span several correlation times. NaN entries stay NaN.
    """
    k = len(refits)
    jk = np.sqrt((k - 1) / k * np.sum((refits - refits.mean(axis=0)) ** 2, axis=0))
    pseudo = k * np.asarray(full, float) - (k - 1) * refits
    between = np.clip(pseudo.var(axis=0, ddof=1) - k * np.square(sigma), 0.0, None)
    return jk, np.sqrt(between)


def honest_covariance(cov: np.ndarray, residuals: np.ndarray, jac: np.ndarray | None = None) -> np.ndarray:
    """A least-squares covariance (P, P) scaled to the correlation in time of what drives each parameter.

    ``cov`` = ``s^2 inv(J^T J)`` (the misfit already in ``s^2``); ``residuals`` (N, k) in time
    order, one row per point. Without ``jac``: ``cov`` times the largest :func:`tau_int` of the
    residuals (right for a mean). With ``jac`` (rows ``i * k + c`` for point ``i``, component
    ``c``; further rows, e.g. a prior, ignored): each parameter's score series ``g_i = sum_c
    J[i k + c] r[i, c]`` (its share of the normal equations) gives its own ``tau_p``, and
    ``cov_pq`` is scaled by ``sqrt(tau_p tau_q)``, each ``tau_p`` at least the residuals' own
    (the larger is kept: each shows a correlation the other can miss) - the effective-sample-size form of a
    heteroscedasticity-and-autocorrelation-consistent (Newey-West) sandwich: with a smooth
    trajectory the regressors are correlated in time too, and a parameter's information comes
    from fewer independent stretches than the residuals alone suggest. NaN entries stay NaN.
    """
    r = np.asarray(residuals, float)
    r = r[:, None] if r.ndim == 1 else r
    cov = np.asarray(cov, float)
    if jac is None:
        return cov * float(np.max(tau_int(r, pooled=False)))
    n, k = r.shape
    j = np.asarray(jac, float)[: n * k].reshape(n, k, -1)
    scores = (j * r[:, :, None]).sum(axis=1)
    tau = np.where(np.any(scores != 0, axis=0), tau_int(scores, pooled=False), 1.0)
    d = np.sqrt(np.maximum(tau, float(np.max(tau_int(r, pooled=False)))))
    return cov * d[:, None] * d[None, :]
