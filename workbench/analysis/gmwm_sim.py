"""Fast draws of the Haar wavelet variance of records of a GMWM model (for its parametric bootstrap).

A record of n samples at dt is never simulated in full: the WV at scale tau = 2 m samples is read
from the means of blocks of M samples (M = 1, 8, 64, ...; the scales of a block size are
m in [8 M, 64 M), its overlapping differences taken every M samples, which for m >= 8 M loses
a few per cent of the estimator's efficiency at most). The block means are simulated exactly:

* the stationary part (white ``wn``, quantization ``qn``, Gauss-Markov ``gm`` and the flicker
  ladder ``fl``) is a Gaussian process whose block-mean autocovariance is known in closed form
  (an AR(1) started stationary, x_{k+1} = p x_k + e: block means c s_k + D_k with s_k the state at
  the block's start, s_{k+1} = p^M s_k + A_k, (A_k, D_k) Gaussian); it is drawn by circulant
  embedding (Dietrich & Newsam 1997; exact for these convex decreasing autocovariances);
* the rate random walk ``rw`` through the joint law of each block's step sum and weighted sum;
* the rate ramp ``dr`` is deterministic.

While a block size leaves more than 2 :data:`CAP` blocks, only :data:`CAP` blocks are simulated
and their WV deviations from the model are scaled to the full length by sqrt of the ratio of
the numbers of differences (a CLT scaling; these scales have hundreds of degrees of freedom); the
first block size that fits gives every remaining scale from a full-length record, so the long
scales, where the WV is skewed and RRW lives, keep their exact small-sample law. Cost per
draw ~3 x 2 CAP samples whatever n.

Public: :data:`CAP`, :func:`block_autocov`, :func:`block_records`, :func:`wv_draws`.
"""

from __future__ import annotations

import numpy as np

CAP = 1 << 13  # blocks simulated per truncated band
BAND = 8  # block size ratio between bands (three octaves)


def _gm_block_law(sigma: float, t_c: float, block: int, dt: float) -> tuple[float, float, float, float, float]:
    """(c, P, var A, var D, cov A D) of block means of an AR(1) of std ``sigma`` and time ``t_c`` s."""
    x = dt / t_c
    j = np.arange(block, dtype=float)  # j = M - 1 - l: innovation l's distance to the block's end
    one_p = -np.expm1(-x)
    pj = np.exp(-x * j)
    w = -np.expm1(-x * j) / one_p / block  # weight of innovation l in the block mean (0 for the last)
    s_e2 = sigma ** 2 * -np.expm1(-2.0 * x)
    c = -np.expm1(-block * x) / one_p / block
    return c, float(np.exp(-block * x)), s_e2 * float(pj @ pj), s_e2 * float(w @ w), s_e2 * float(pj @ w)


def block_autocov(kinds: tuple[str, ...], theta: np.ndarray, n: int, block: int, dt: float,
                  ladder: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Autocovariance (n + 1,) at lags 0..n (u^2) of the block means (``block`` samples) of the
    model's stationary processes (wn, qn, gm, fl with ``ladder`` = (times s, variances per B^2))."""
    h = np.arange(n + 1, dtype=float)
    g = np.zeros(n + 1)
    i = 0
    for k in kinds:
        if k in ("wn", "qn", "fl"):
            v = float(theta[i])
            i += 1
            if k == "wn":
                g[0] += v * v / (block * dt)
            elif k == "qn":
                q2 = (v / (block * dt)) ** 2
                g[0] += 2.0 * q2
                g[1] -= q2
            else:
                for t_c, var in zip(*ladder):
                    g += _gm_autocov(v * np.sqrt(var), t_c, block, dt, h)
        elif k == "gm":
            g += _gm_autocov(float(theta[i]), float(theta[i + 1]), block, dt, h)
            i += 2
        else:
            i += 1
    return g


def _gm_autocov(sigma: float, t_c: float, block: int, dt: float, h: np.ndarray) -> np.ndarray:
    c, p, _, var_d, cov_ad = _gm_block_law(sigma, t_c, block, dt)
    out = c * (p * c * sigma ** 2 + cov_ad) * p ** np.maximum(h - 1.0, 0.0)
    out[0] = c * c * sigma ** 2 + var_d
    return out


def _stationary(g: np.ndarray, n: int, records: int, rng: np.random.Generator) -> np.ndarray:
    """(n, records) Gaussian records of autocovariance ``g`` (lags 0..n) by circulant embedding."""
    c = np.concatenate([g[:n + 1], g[n - 1:0:-1]])  # size 2 n
    lam = np.sqrt(np.maximum(np.fft.fft(c).real, 0.0) / len(c))
    pairs = (records + 1) // 2
    z = rng.standard_normal((len(c), pairs)) + 1j * rng.standard_normal((len(c), pairs))
    w = np.fft.fft(lam[:, None] * z, axis=0)[:n]
    return np.concatenate([w.real, w.imag], axis=1)[:, :records]


def block_records(kinds: tuple[str, ...], theta: np.ndarray, n: int, block: int, dt: float, records: int,
                  rng: np.random.Generator, ladder: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """(n, records) block means over ``block`` samples of records of the model (u)."""
    y = _stationary(block_autocov(kinds, theta, n, block, dt, ladder), n, records, rng)
    i = 0
    for k in kinds:
        if k == "gm":
            i += 2
            continue
        v = float(theta[i])
        i += 1
        if k == "rw" and v > 0:
            m = float(block)
            # step sum T and weighted sum U of the block's steps: var T = M s2, cov = (M + 1) / 2 s2,
            # var U = (M + 1)(2 M + 1) / (6 M) s2 (singular at M = 1: U = T)
            s2 = v * v * dt
            a = np.sqrt(m * s2)
            b = (m + 1) / 2 * s2 / a
            d = np.sqrt(max((m + 1) * (2 * m + 1) / (6 * m) * s2 - b * b, 0.0))
            z = rng.standard_normal((2, n, records))
            steps, inner = a * z[0], b * z[0] + d * z[1]
            start = np.cumsum(steps, axis=0) - steps  # the walk before each block
            y += start + inner
        elif k == "dr":
            y += (v * dt * (block * np.arange(n) + (block - 1) / 2.0))[:, None]
    return y


def _wv_of(y: np.ndarray, lags: np.ndarray) -> np.ndarray:
    """Haar WV (K, C) of block means ``y`` (n, C) at lags (blocks): overlapping AVAR / 2."""
    from workbench.analysis.allan import phase, squared_sums

    x = phase(y, 1.0)
    return squared_sums(x, lags, "oadev") / (4.0 * lags[:, None].astype(float) ** 2 * (x.shape[1] - 2 * lags[:, None]))


def wv_draws(kinds: tuple[str, ...], theta: np.ndarray, n: int, dt: float, tau: np.ndarray, records: int,
             rng: np.random.Generator, ladder: tuple[np.ndarray, np.ndarray], expected: np.ndarray) -> np.ndarray:
    """(records, J) Haar WV at scales ``tau`` (samples, 2 m) of records of n samples of the model;
    ``expected`` (J,) the model's WV (the centre the truncated bands' deviations are scaled about)."""
    m = (np.asarray(tau) // 2).astype(np.int64)
    out = np.empty((records, len(m)))
    block, lo = 1, 0
    while lo < len(m):
        full = n // block <= 2 * CAP
        top = len(m) if full else int(np.searchsorted(m, BAND * BAND * block if block > 1 else BAND * BAND))
        sel = slice(lo, top)
        length = n // block if full else CAP
        wv = _wv_of(block_records(kinds, theta, length, block, dt, records, rng, ladder), m[sel] // block).T
        if not full:
            t = 2.0 * m[sel]
            wv = expected[sel] + (wv - expected[sel]) * np.sqrt((length * block - t + 1) / (n - t + 1))
        out[:, sel] = wv
        lo, block = top, block * BAND
    return out
