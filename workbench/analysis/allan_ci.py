"""Confidence intervals of Allan-type deviations: noise identification, EDF, chi-squared.

At every tau and channel the dominant power-law noise is identified from the lag-1
autocorrelation of the phase decimated by m (Riley & Greenhall 2004): after a quadratic
detrend the series is differenced until delta = r1 / (1 + r1) < 0.25 (at most d times, d = 2
for Allan, 3 for Hadamard variances); alpha = 2 - 2 (delta + d_used), rounded. For rate data
alpha = 0 is white rate noise (ARW/VRW), -1 flicker (bias instability), -2 random walk (RRW),
2 white phase (quantization). Where fewer than 100 decimated points remain, the short
series gives an unreliable exponent: there the exponent carried over from the last
identified tau and the one from the curve's local slope are both candidates, and the one
with fewer degrees of freedom (the wider interval) is used.

The equivalent degrees of freedom follow Greenhall & Riley, "Uncertainty of stability
variances based on finite differences" (2003): edf = 1 / inv_edf with
``inv_edf = BasicSum(J, M, S, F, alpha, d) / (M sz(0)^2)``. Where J exceeds ``J_MAX`` the sum is
evaluated on the rescaled problem (same r = M / S, J_MAX terms), which is the construction
behind the paper's large-J tables. The interval of the variance is then
``[edf s^2 / chi2(0.975, edf), edf s^2 / chi2(0.025, edf)]``.

Public: :func:`chi2_ppf`, :func:`noise_id`, :func:`noise_id_decimated`, :func:`noise_id_spread`, :func:`identify`, :func:`identify_decimated`,
:func:`alpha_from_slope`, :func:`edf_greenhall`, :func:`confidence`, :class:`DeviationCI`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from math import comb

import numpy as np

from workbench.analysis.allan import DeviationCurve
from workbench.analysis.chi2 import chi2_ppf

J_MAX = 2000  # terms of the Greenhall sum evaluated directly (the paper uses 100)
MIN_POINTS_ID = 100  # decimated phase points needed for the lag-1 noise identification
MAX_POINTS_ID = 1 << 16  # decimated points used (r1 then has a standard error ~0.004)
_D = {"oadev": 2, "mdev": 2, "ohdev": 3}
_ALPHA_RANGE = {"oadev": (-2, 2), "mdev": (-2, 2), "ohdev": (-4, 2)}


@dataclass(frozen=True)
class DeviationCI:
    """A deviation curve with its confidence interval.

    ``alpha`` (K, C) identified power-law exponent of the rate noise (S_y ~ f^alpha);
    ``edf`` (K, C) equivalent degrees of freedom; ``lo``/``hi`` (K, C) deviation bounds in the
    curve's unit at confidence ``level`` (two-sided, chi-squared).
    """

    curve: DeviationCurve
    alpha: np.ndarray
    edf: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    level: float


# -- noise identification -------------------------------------------------------------------

def _lag1(z: np.ndarray) -> float:
    z = z - z.mean()
    den = float(np.sum(z * z))  # not np.dot: BLAS threads oversubscribe small shared machines
    return float(np.sum(z[:-1] * z[1:]) / den) if den > 0 else 0.0


def noise_id(x: np.ndarray, m: int, dmax: int) -> float:
    """Power-law exponent alpha (not rounded) of the noise in phase ``x`` (L,) at lag ``m``.

    Lag-1 autocorrelation method (Riley & Greenhall 2004) on the phase decimated by ``m``
    (its first :data:`MAX_POINTS_ID` points).
    """
    return noise_id_decimated(x[::m][:MAX_POINTS_ID], dmax)


def noise_id_decimated(z: np.ndarray, dmax: int) -> float:
    """Power-law exponent alpha (not rounded) from an already decimated phase ``z`` (L_m,) (any unit)."""
    return noise_id_spread(z, dmax)[0]


def noise_id_spread(z: np.ndarray, dmax: int) -> tuple[float, float]:
    """(alpha, its standard error) from a decimated phase ``z``: the lag-1 estimate as
    :func:`noise_id_decimated`, and se = 2 se(r1) / (1 + r1)^2 with se(r1) = 1 / sqrt(L) of the
    series finally differenced (delta method on alpha = 2 - 2 (r1 / (1 + r1) + d))."""
    z = np.asarray(z, float)
    t = np.arange(len(z), dtype=float)
    z = z - np.polyval(np.polyfit(t, z, 2), t)
    d = 0
    while True:
        r1 = _lag1(z)
        delta = r1 / (1.0 + r1)
        if delta < 0.25 or d >= dmax:
            se = 2.0 / (max(1.0 + r1, 1e-3) ** 2 * np.sqrt(max(len(z), 1)))
            return 2.0 - 2.0 * (delta + d), float(se)
        z = np.diff(z)
        d += 1


def identify(x: np.ndarray, m: np.ndarray, kind: str) -> np.ndarray:
    """Rounded alpha (K, C) for phase ``x`` (C, L) at factors ``m``; NaN where the decimated
    series has fewer than :data:`MIN_POINTS_ID` points (too short to identify reliably)."""
    return identify_decimated([x[:, ::int(mk)][:, :MAX_POINTS_ID] for mk in m], x.shape[1], m, kind)


def identify_decimated(z: Sequence[np.ndarray], n_phase: int, m: np.ndarray, kind: str) -> np.ndarray:
    """:func:`identify` from the decimated phases ``z[k]`` (C, >= min(ceil(L / m_k), MAX_POINTS_ID)),
    ``x[:, ::m_k]`` of a record of ``n_phase`` = L phase points, of which the first
    :data:`MAX_POINTS_ID` are used (a streamed record keeps only those: bounded memory)."""
    lo, hi = _ALPHA_RANGE[kind]
    out = np.full((len(m), len(z[0]) if len(z) else 0), np.nan)
    for k, mk in enumerate(m):
        if n_phase // mk >= MIN_POINTS_ID:
            for c in range(out.shape[1]):
                out[k, c] = float(np.clip(np.round(noise_id_decimated(z[k][c][:MAX_POINTS_ID], _D[kind])), lo, hi))
    return out


def alpha_from_slope(curve: DeviationCurve) -> np.ndarray:
    """Rounded alpha (K, C) from the local log-log slope mu of an ADEV/HDEV curve, alpha = -2 mu - 1.

    For records whose phase is not at hand (streamed files); valid for -3 < alpha <= 1 (white
    and flicker phase noise both show mu = -1, and are told apart only by the lag-1 method).
    """
    lo, hi = _ALPHA_RANGE[curve.kind]
    mu = np.gradient(np.log(curve.dev), np.log(curve.tau), axis=0) if len(curve.tau) > 1 else \
        np.full(curve.dev.shape, -0.5)
    return np.clip(np.round(-2.0 * mu - 1.0), lo, min(hi, 1))


# -- Greenhall EDF -------------------------------------------------------------------------

def _sw(t: np.ndarray, alpha: int) -> np.ndarray:
    """Generalised autocovariance of the phase for noise exponent alpha (Greenhall eq. 8)."""
    t = np.asarray(t, float)
    a = abs(t)
    if alpha in (2, 0, -2, -4):
        power = {2: 1, 0: 3, -2: 5, -4: 7}[alpha]
        return -a if alpha == 2 else a ** power
    power = {1: 2, -1: 4, -3: 6}[alpha]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(a > 0, t ** power * np.log(np.where(a > 0, a, 1.0)), 0.0)


def _sx(t: np.ndarray, f: float, alpha: int) -> np.ndarray:
    if np.isinf(f):
        return _sw(t, alpha + 2)
    return f ** 2 * (2.0 * _sw(t, alpha) - _sw(t - 1.0 / f, alpha) - _sw(t + 1.0 / f, alpha))


def _sz(t: np.ndarray, f: float, alpha: int, d: int) -> np.ndarray:
    """Filtered covariance: the d-th central binomial difference of sx (Greenhall eq. 11)."""
    out = np.zeros_like(np.asarray(t, float))
    for k in range(-d, d + 1):
        out = out + (-1) ** k * comb(2 * d, d + k) * _sx(t + k, f, alpha)
    return out


def _basic_sum(j: int, big_m: float, s: float, f: float, alpha: int, d: int) -> float:
    jj = np.arange(1, j, dtype=float)
    first = _sz(np.array(0.0), f, alpha, d) ** 2
    second = (1.0 - j / big_m) * _sz(np.array(j / s), f, alpha, d) ** 2
    third = np.sum(2.0 * (1.0 - jj / big_m) * _sz(jj / s, f, alpha, d) ** 2)
    return float(first + second + third)


@lru_cache(maxsize=4096)
def edf_greenhall(alpha: int, d: int, m: int, n_phase: int, overlapping: bool = True,
                  modified: bool = False) -> float:
    """Equivalent degrees of freedom of a d-th difference variance (Greenhall & Riley 2003).

    ``alpha`` noise exponent (integer, alpha + 2d > 1), ``m`` averaging factor, ``n_phase``
    number of phase points; ``overlapping`` (S = m) and ``modified`` (F = 1) choose the
    estimator: oadev (d=2, overlapping), mdev (d=2, overlapping, modified), ohdev (d=3).
    """
    alpha = int(alpha)
    f = 1.0 if modified else float(m)
    s = float(m) if overlapping else 1.0
    ell = m / f + m * d
    big_m = 1.0 + np.floor(s * (n_phase - ell) / m)
    j = min(big_m, (d + 1) * s)
    if not modified and alpha == 2 and np.ceil(big_m / s) > d:
        # white phase, unmodified: closed form (Greenhall & Riley case 4)
        a0 = comb(4 * d, 2 * d) / comb(2 * d, d) ** 2
        return float(1.0 / ((a0 - d / 2.0 / (big_m / s)) / big_m))
    if not modified and alpha <= 0 and m * (d + 1) > J_MAX:
        f = np.inf  # F = m large: the F -> inf limit avoids cancellation in sx
    if j > J_MAX:  # rescale to J_MAX terms, keeping r = M / S and the shape of the sum
        scale = J_MAX / j
        big_m, s, j = big_m * scale, s * scale, J_MAX
    inv = _basic_sum(int(j), big_m, s, f, alpha, d) / (_sz(np.array(0.0), f, alpha, d) ** 2 * big_m)
    return float(1.0 / inv)


# -- intervals -----------------------------------------------------------------------------

def confidence(curve: DeviationCurve, x: np.ndarray | None = None, alpha: np.ndarray | None = None,
               level: float = 0.95) -> DeviationCI:
    """Chi-squared interval of every point of ``curve`` at two-sided confidence ``level``.

    The noise exponent comes from ``alpha`` (K, C) if given, else is identified from the
    phase ``x`` (C, L) the curve was computed from (:func:`workbench.analysis.allan.phase`);
    NaN exponents (taus too long to identify) are filled as described in the module docstring.
    """
    if alpha is None:
        if x is None:
            raise ValueError("confidence: give the phase x or the noise exponents alpha")
        alpha = identify(x, curve.m, curve.kind)
    alpha = _fill_short(curve, alpha)
    edf = _edf(curve, alpha)
    q = (1.0 - level) / 2.0
    lo = curve.dev * np.sqrt(edf / chi2_ppf(1.0 - q, edf))
    hi = curve.dev * np.sqrt(edf / chi2_ppf(q, edf))
    return DeviationCI(curve, alpha, edf, lo, hi, level)


def _edf(curve: DeviationCurve, alpha: np.ndarray) -> np.ndarray:
    return np.array([[_edf_one(curve, k, a) for a in alpha[k]] for k in range(len(curve.m))]).reshape(alpha.shape)


def _fill_short(curve: DeviationCurve, alpha: np.ndarray) -> np.ndarray:
    """Fill the taus too long to identify: of the exponent carried from the last identified
    tau and the one from the curve's local slope, take the one giving fewer degrees of
    freedom (the wider, conservative interval)."""
    slope = alpha_from_slope(curve)
    out = alpha.copy()
    for c in range(alpha.shape[1]):
        last = slope[0, c]
        for k in range(len(curve.m)):
            if np.isfinite(alpha[k, c]):
                last = alpha[k, c]
                continue
            cands = {last, slope[k, c]}
            out[k, c] = min(cands, key=lambda a: _edf_one(curve, k, a))
    return out


def _edf_one(curve: DeviationCurve, k: int, a: float) -> float:
    """EDF of point k of ``curve`` for noise exponent ``a``."""
    return edf_greenhall(int(a), _D[curve.kind], int(curve.m[k]), curve.n_samples + 1, True, curve.kind == "mdev")
