"""Confidence intervals of the stability family (:mod:`workbench.analysis.stability`).

Noise type per tau: lag-1 autocorrelation of the phase decimated by m (Riley & Greenhall 2004,
:func:`workbench.analysis.allan_ci.noise_id_decimated`) while at least
:data:`MIN_POINTS_LAG1` decimated points remain; beyond, the exponent carried from the last
identified tau (Stable32 switches to the B1 / R(n) ratios there; here the carried exponent is
compared with the one from the curve's local slope and the one giving fewer degrees of freedom is
kept, so long-tau intervals are never narrower than either reading).

EDF: Greenhall & Riley (2003) for the finite-difference statistics (adev / hdev: S = 1,
oadev / ohdev: S = m, mdev / tdev: F = 1; :func:`workbench.analysis.allan_ci.edf_greenhall`),
with the counts of used pairs when gaps were skipped. The total family, with N the number of
phase points (T = N tau0, as Stable32):

* totdev, FM noise: NIST SP 1065 table 7, edf = b N / m - c; below m = 4 at most the OADEV's
  (at m = 1 TOTDEV is the OADEV: table 7 claims 1.5 N there, twice a white-FM record's 2N / 3).
  Flicker PM: the OADEV's. White PM: 1 / edf = 1 / edf_OADEV + (m / N)^2 / 1.5. The reflected
  extension puts the two end points into ~2m of the N terms, a shared part whose weight grows as
  (m / N)^2; the 1.5 is fitted to the Monte Carlo EDF (N = 256, 1001, 4096, m = 8 .. N / 4: within
  -30 .. +8 % of it; at N = 1001, m = 64, 128, 256 it gives 205, 75, 22 where the Monte Carlo
  gives 189, 78, 29 and the OADEV's is 467, 420, 344).
* mtotdev / ttotdev: below m = 10 the Greenhall MDEV EDF (as Stable32), from m = 10 SP 1065
  table 8 (edf = b N / m - c). Stable32 uses larger coefficients there (its bounds imply
  b = 1.33, c = 1.89 for white FM, 1.73 / 2.99 for flicker PM, against table 8's 1.10 / 1.2 and
  1.20 / 1.40), which the Monte Carlo EDF of the same estimator does not support
  (benchmarks/allan_ci_edf.py): ours are the wider.
* htotdev: at m = 1 (where it is the OHDEV) the OHDEV's; below m = 16, and for flicker PM at every
  m, the simple formulas of SP 1065 (Howe, Allan & Barnes), from m = 16 for FM noise Howe et
  al.'s (PTTI 2000) edf = (N / m) / (b0 + b1 m / N), all as Stable32; noise steeper than
  random-walk FM: the OHDEV's. White PM from m = 2: 0.6 N. Stable32 takes the simple white-PM
  formula, ~0.5 N falling to 0.33 N at m = N / 4, but the Monte Carlo EDF of the estimator is
  0.58-0.81 N at every m from 2 to N / 4 (N = 256, 1001, 4096): with it the intervals covered
  98.2 % instead of 95 %; 0.6 N is that EDF's floor (narrower than Stable32's by <= 0.3 % up to
  m = 16, 0.7 % at m = N / 4).
* Theo1 / TheoH beyond the oadev part: Howe & Tasset's Theo1 EDF (SP 1065), r = 0.75 m.

MTIE and TIE rms get no interval (NaN). The interval is the chi-squared one at two-sided ``level``.

Public: :class:`StabilityCI`, :func:`intervals`, :func:`edf_of`, :func:`edf_of_many`, :func:`edf_simple`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.analysis.allan_ci import (MAX_POINTS_ID, chi2_ppf, edf_greenhall_many, noise_id_spread, pick_wider,
                                        round_alpha)
from workbench.analysis.stability import Stability, stability
from workbench.errors import AnalysisError

AMBIGUOUS_SE = 1.0  # standard errors of the lag-1 alpha within which a second noise type is considered
FLICKER_AVERAGED = 1.5  # alpha on the block-averaged phase below which "white PM" is flicker PM
MIN_POINTS_LAG1 = 30  # decimated points for the lag-1 method (Riley & Greenhall: reliable from ~30)
_GREENHALL = {"adev": (2, False, False), "oadev": (2, True, False), "mdev": (2, True, True),
              "tdev": (2, True, True), "hdev": (3, False, False), "ohdev": (3, True, False)}
# d, overlapping (S = m), modified (F = 1)
_TOT = {0: (1.50, 0.0), -1: (1.17, 0.22), -2: (0.93, 0.36)}  # SP 1065 table 7, alpha: (b, c)
_MTOT = {2: (1.90, 2.1), 1: (1.20, 1.40), 0: (1.10, 1.2), -1: (0.85, 0.50), -2: (0.75, 0.31)}  # table 8
_HTOT = {0: (0.559, 1.004), -1: (0.868, 1.140), -2: (0.938, 1.696)}  # Howe et al. 2000, alpha: (b0, b1)
NO_INTERVAL = ("mtie", "tierms")
TOT_OADEV_BELOW = 4  # totdev below this m: at most the OADEV's EDF
TOT_WPM_ENDS = 1.5  # totdev, white PM: 1 / edf gains (m / N)^2 / TOT_WPM_ENDS (module docstring)
MTOT_MDEV_BELOW = 10  # mtotdev / ttotdev below this m take the Greenhall MDEV EDF
HTOT_FROM = 16  # htotdev from this m (FM noise) takes Howe's HTOT EDF
HTOT_WPM = 0.6  # htotdev, white PM, m >= 2: edf = HTOT_WPM N (module docstring)


@dataclass(frozen=True)
class StabilityCI:
    """A :class:`Stability` curve with per-tau ``alpha`` (noise exponent, frequency PSD ~ f^alpha),
    ``edf`` and the deviation bounds ``lo`` / ``hi`` at two-sided ``level``."""

    curve: Stability
    alpha: np.ndarray
    edf: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    level: float


def _theo1_edf(alpha: np.ndarray, n: int, m: np.ndarray) -> np.ndarray:
    """Theo1 EDF (Howe & Tasset; SP 1065 table 11), r = 0.75 m, N phase points (``alpha`` in -2 .. 2)."""
    r = 0.75 * m
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.select([alpha == 2, alpha == 1, alpha == 0, alpha == -1], [
            0.86 * (n + 1) * (n - 4.0 * r / 3.0) / (n - r) * r / (r + 1.14),
            (4.798 * n ** 2 - 6.374 * n * r + 12.387 * r) / (np.sqrt(r + 36.6) * (n - r)) * r / (r + 0.3),
            ((4.1 * n + 0.8) / r - (3.1 * n + 6.5) / n) * r ** 1.5 / (r ** 1.5 + 5.2),
            (2.0 * n ** 2 - 1.3 * n * r - 3.5 * r) / (n * r) * r ** 3 / (r ** 3 + 2.3)],
            (4.4 * n - 2.0) / (2.9 * r) * ((4.4 * n - 1) ** 2 - 8.6 * r * (4.4 * n - 1) + 11.4 * r ** 2)
            / (4.4 * n - 3) ** 2)


def _edf_simple_many(alpha: np.ndarray, n: int, m: np.ndarray) -> np.ndarray:
    m = m.astype(float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.select([alpha == 2, alpha == 1, alpha == 0, alpha == -1], [
            (n + 1) * (n - 2 * m) / (2.0 * (n - m)),
            np.exp(np.sqrt(np.log((n - 1) / (2.0 * m)) * np.log((2 * m + 1) * (n - 1) / 4.0))),
            (3.0 * (n - 1) / (2 * m) - 2.0 * (n - 2) / n) * 4 * m ** 2 / (4 * m ** 2 + 5),
            np.where(m == 1, 2.0 * (n - 2) / (2.3 * n - 4.9), 5.0 * n ** 2 / (4 * m * (n + 3 * m)))],
            (n - 2.0) / m * ((n - 1) ** 2 - 3.0 * m * (n - 1) + 4.0 * m ** 2) / (n - 3.0) ** 2)


def edf_simple(alpha: int, n: int, m: int) -> float:
    """The simple EDF formulas of NIST SP 1065 (Howe, Allan & Barnes 1981) for noise exponent
    ``alpha`` (2 .. -2) at factor ``m`` on ``n`` phase points (as allantools' ``edf_simple``)."""
    return float(_edf_simple_many(np.array([int(alpha)]), n, np.array([m]))[0])


def edf_of(stat: str, alpha: int, m: int, n_phase: int, n_used: int | None = None) -> float:
    """Equivalent degrees of freedom of ``stat`` at factor ``m`` for noise exponent ``alpha`` on a
    record of ``n_phase`` phase points (``n_used``: pairs actually used when gaps were skipped;
    the EDF is that of a gap-free record with as many pairs)."""
    return float(edf_of_many(stat, np.array([int(alpha)]), np.array([m]), n_phase,
                             None if n_used is None else np.array([n_used]))[0])


def edf_of_many(stat: str, alpha: np.ndarray, m: np.ndarray, n_phase: int,
                n_used: np.ndarray | None = None) -> np.ndarray:
    """:func:`edf_of` at every factor of ``m`` (K,) with exponents ``alpha`` (K,) (``n_used`` (K,) or None)."""
    alpha = np.asarray(alpha, float).astype(np.int64)
    m = np.asarray(m).astype(np.int64)
    if stat in NO_INTERVAL:
        return np.full(len(m), np.nan)
    if stat in _GREENHALL:
        d, overlapping, modified = _GREENHALL[stat]
        n_rec = np.full(len(m), n_phase, dtype=np.int64)
        if n_used is not None:  # the record a gap-free run of n_used terms would have
            n_used = np.asarray(n_used).astype(np.int64)
            if overlapping:
                n_rec = n_used + (3 * m - 1 if modified else d * m)
            else:
                n_rec = (n_used + d - 1) * m + 1
        # Greenhall needs alpha + 2d > 1
        return edf_greenhall_many(np.maximum(alpha, 1 - 2 * d + 1), d, m, n_rec, overlapping, modified)
    out = np.empty(len(m))
    mf = m.astype(float)
    if stat == "totdev":
        oadev = edf_greenhall_many(np.maximum(alpha, -2), 2, m, n_phase, True, False)
        fm = np.minimum(np.maximum(alpha, -2), 0)
        b = np.select([fm == 0, fm == -1], [_TOT[0][0], _TOT[-1][0]], _TOT[-2][0])
        c = np.select([fm == 0, fm == -1], [_TOT[0][1], _TOT[-1][1]], _TOT[-2][1])
        table = b * n_phase / mf - c
        fm_edf = np.where(m < TOT_OADEV_BELOW, np.minimum(table, oadev), table)
        # white PM: the reflected ends' share (see the module docstring); flicker PM: the OADEV's
        return np.select([alpha == 2, alpha > 0], [1.0 / (1.0 / oadev + (mf / n_phase) ** 2 / TOT_WPM_ENDS), oadev],
                         fm_edf)
    if stat in ("mtotdev", "ttotdev"):
        short = m < MTOT_MDEV_BELOW  # short taus: the MDEV's degrees of freedom (see the module docstring)
        if short.any():
            out[short] = edf_greenhall_many(np.maximum(alpha[short], -2), 2, m[short], n_phase, True, True)
        a = np.clip(alpha[~short], -2, 2)
        b = np.array([_MTOT[int(v)][0] for v in a])
        c = np.array([_MTOT[int(v)][1] for v in a])
        out[~short] = b * n_phase / mf[~short] - c
        return out
    if stat == "htotdev":
        ohdev = (m == 1) | (alpha < -2)  # htotdev is the ohdev at m = 1; no total formula below RW FM
        simple = ~ohdev & (alpha != 2) & ((m < HTOT_FROM) | (alpha > 0))
        howe = ~ohdev & (alpha != 2) & ~simple
        if ohdev.any():
            out[ohdev] = edf_greenhall_many(np.maximum(alpha[ohdev], -4), 3, m[ohdev], n_phase, True, False)
        out[~ohdev & (alpha == 2)] = HTOT_WPM * n_phase  # white PM: the Monte Carlo floor (module docstring)
        out[simple] = _edf_simple_many(alpha[simple], n_phase, m[simple])
        b0 = np.array([_HTOT[int(v)][0] for v in alpha[howe]])
        b1 = np.array([_HTOT[int(v)][1] for v in alpha[howe]])
        out[howe] = n_phase / mf[howe] / (b0 + b1 * mf[howe] / n_phase)
        return out
    if stat in ("theo1", "theoh"):
        return _theo1_edf(np.clip(alpha, -2, 2), n_phase, mf)
    raise ValueError(stat)


def _identify(x: np.ndarray, m: np.ndarray, dmax: int) -> tuple[np.ndarray, np.ndarray]:
    """Rounded alpha per factor from the lag-1 ACF of the decimated phase (NaN: too few points),
    and, where the estimate lies within AMBIGUOUS_SE standard errors of the white / flicker PM
    boundary, the other of the two (else the same value).

    White PM read on the decimated phase is checked on the phase averaged over blocks of m:
    decimation folds flicker PM's power above the new Nyquist frequency into a white floor (on
    64 decimated points flicker PM reads as white in ~90 % of records, and the white-PM EDF is
    ~4x too large), averaging does not; white PM stays white (alpha ~2) after averaging, flicker PM
    reads ~0.6 there, so below FLICKER_AVERAGED the exponent is flicker PM."""
    out = np.full(len(m), np.nan)
    other = np.full(len(m), np.nan)
    lo_a = -2 if dmax == 2 else -4
    finite = np.isfinite(x)
    xs = x if finite.all() else np.interp(np.arange(len(x)), np.flatnonzero(finite), x[finite])
    for k, mk in enumerate(m):
        mk = int(mk)
        z = xs[::mk][:MAX_POINTS_ID]
        if len(z) >= MIN_POINTS_LAG1:
            a, se = noise_id_spread(z, dmax)
            out[k] = round_alpha(a, lo_a, 2)
            if out[k] == 2 and mk > 1:
                blocks = min(len(xs) // mk, MAX_POINTS_ID)
                if noise_id_spread(xs[:blocks * mk].reshape(blocks, mk).mean(axis=1), dmax)[0] < FLICKER_AVERAGED:
                    out[k] = a = 1.0
            ends = [round_alpha(a + s * AMBIGUOUS_SE * se, lo_a, 2) for s in (-1.0, 1.0)]
            # only white vs flicker PM, where the lag-1 method is weakest (the other pairs stay as
            # identified: their types agree with Stable32's and their coverage is within 95 +- 2 %)
            other[k] = next((e for e in ends if e != out[k] and {e, out[k]} <= {1.0, 2.0}), out[k])
    return out, other


def intervals(curve: Stability, x: np.ndarray, level: float = 0.95, alpha: np.ndarray | None = None) -> StabilityCI:
    """Chi-squared intervals of ``curve`` computed from phase ``x`` (L,) (:func:`stability.to_phase`).

    ``alpha`` (K,) fixes the noise exponents (as Stable32's manual noise type); by default they are
    identified as in the module docstring.
    """
    k_n = len(curve.m)
    if curve.stat in NO_INTERVAL:
        nan = np.full(k_n, np.nan)
        return StabilityCI(curve, nan, nan, nan.copy(), nan.copy(), level)
    if alpha is None:
        dmax = 3 if curve.stat in ("hdev", "ohdev", "htotdev") else 2
        m_id = np.maximum(np.round(0.75 * curve.m), 1) if curve.stat == "theo1" else curve.m
        alpha, other = _identify(x, m_id, dmax)
        alpha = _conservative(curve, alpha, other)
        alpha = _fill(curve, alpha, x)
    alpha = np.asarray(alpha, float)
    edf = np.empty(k_n)
    if curve.stat == "theoh":  # the oadev part at tau = m / rate, Theo1 beyond
        theo = curve.tau != curve.m / curve.rate
        edf[theo] = edf_of_many("theo1", alpha[theo], curve.m[theo], curve.n_phase)
        edf[~theo] = edf_of_many("oadev", alpha[~theo], curve.m[~theo], curve.n_phase)
    else:
        edf = edf_of_many(curve.stat, alpha, curve.m, curve.n_phase, curve.n if curve.stat in _GREENHALL else None)
    edf = np.maximum(edf, 1e-3)
    q = (1.0 - level) / 2.0
    lo = curve.dev * np.sqrt(edf / chi2_ppf(1.0 - q, edf))
    hi = curve.dev * np.sqrt(edf / chi2_ppf(q, edf))
    return StabilityCI(curve, alpha, edf, lo, hi, level)


def _wider(curve: Stability, first: np.ndarray, second: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """At the taus ``rows``, of the exponents ``first`` and ``second`` the one with fewer degrees of freedom."""
    stat = curve.stat if curve.stat != "theoh" else "theo1"
    return pick_wider(first, second, lambda a, i: edf_of_many(stat, a, curve.m[rows[i]], curve.n_phase))


def _conservative(curve: Stability, alpha: np.ndarray, other: np.ndarray) -> np.ndarray:
    """Where the identification is ambiguous (``other`` differs), the exponent with fewer degrees
    of freedom: flicker PM read as white PM on 30-300 decimated points would otherwise give
    intervals covering ~0.9 instead of 0.95 (benchmarks/allan_ci_coverage.py)."""
    out = alpha.copy()
    rows = np.flatnonzero(np.isfinite(alpha) & (other != alpha))
    out[rows] = _wider(curve, alpha[rows], other[rows], rows)
    return out


def _fill(curve: Stability, alpha: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Exponents of the taus too long to identify: of the one carried from the last identified tau
    and the one from the local slope of the curve, the one giving fewer degrees of freedom; white
    vs flicker PM (the slope cannot tell them apart) by Stable32's R(n) ratio instead."""
    out = alpha.copy()
    if len(curve.tau) > 1:
        mu = np.gradient(np.log(np.maximum(curve.dev, 1e-300)), np.log(curve.tau))
        if curve.stat in ("tdev", "ttotdev"):
            mu = mu - 1.0
        slope = np.clip(np.round(-2.0 * mu - 1.0), -2, 1)
    else:
        slope = np.zeros(1)
    known = np.isfinite(alpha)
    carried = np.maximum.accumulate(np.where(known, np.arange(len(alpha)), -1))
    last = np.where(carried >= 0, alpha[np.maximum(carried, 0)], slope[0])
    rows = np.flatnonzero(~known)
    lo, hi = np.minimum(last[rows], slope[rows]), np.maximum(last[rows], slope[rows])
    pm = rows[(lo == 1.0) & (hi == 2.0)]  # white or flicker PM: by the R(n) ratio
    ratio = _pm_by_ratio(x, np.maximum(np.round(curve.tau[pm] * curve.rate).astype(np.int64), 1))
    out[pm[np.isfinite(ratio)]] = ratio[np.isfinite(ratio)]
    rest = rows[~np.isin(rows, pm[np.isfinite(ratio)])]
    out[rest] = _wider(curve, last[rest], slope[rest], rest)
    return out


def _pm_by_ratio(x: np.ndarray, m: np.ndarray) -> np.ndarray:
    """White (2) or flicker (1) PM at factors ``m`` (K,) of phase ``x`` from R(n) = MVAR / AVAR (Riley,
    SP 1065 5.6): 1 / m for white PM, 3.37 / (1.04 + 3 ln(pi m)) for flicker PM (bandwidth the
    Nyquist frequency); the boundary is their geometric mean, at most 3 / m (white PM's ratio
    scatters by ~1 / m at long taus, flicker PM's far more: a tight white-PM side keeps flicker PM
    from being read as white, the optimistic error). NaN where MVAR needs more than the record
    (3 m + 1 points) or m < 2."""
    out = np.full(len(m), np.nan)
    ok = (m >= 2) & (3 * m + 1 <= len(x))
    if ok.any():
        mo = np.unique(m[ok])
        mvar, avar = (stability(x, 1.0, stat, "phase", mo) for stat in ("mdev", "oadev"))
        if len(mvar.m) != len(mo) or len(avar.m) != len(mo):
            raise AnalysisError(f"R(n) noise identification: no complete difference at some of m = {mo.tolist()}")
        ratio = (mvar.dev / avar.dev)[np.searchsorted(mo, m[ok])] ** 2
        flicker = 3.37 / (1.04 + 3.0 * np.log(np.pi * m[ok]))
        out[ok] = np.where(ratio < np.minimum(np.sqrt(flicker / m[ok]), 3.0 / m[ok]), 2.0, 1.0)
    return out
