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

Public: :func:`chi2_ppf`, :func:`detrend_quadratic`, :func:`noise_id`, :func:`noise_id_decimated`, :func:`noise_id_spread`,
:func:`round_alpha`, :func:`identify`, :func:`identify_decimated`, :func:`alpha_from_slope`, :func:`edf_greenhall`,
:func:`edf_greenhall_many`, :func:`pick_wider`, :func:`confidence`, :class:`DeviationCI`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from math import comb

import numpy as np

from workbench.analysis.allan import DeviationCurve
from workbench.analysis.chi2 import chi2_ppf
from workbench.errors import AnalysisError

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
    # array methods, not np.mean / np.sum (the same sums; their wrappers cost ~5 us a call, 3 calls per
    # difference level and tau of --taus all); not np.dot: BLAS threads oversubscribe small shared machines
    z = z - z.sum() / len(z)
    den = float((z * z).sum())
    return float((z[:-1] * z[1:]).sum() / den) if den > 0 else 0.0


def detrend_quadratic(z: np.ndarray) -> np.ndarray:
    """Residual (L,) of the least-squares quadratic in the index fitted to ``z`` (L,) (as
    ``z - polyval(polyfit(t, z, 2), t)``, to ~1e-15 of ``z``'s range): a projection on the basis
    1, u, u^2 - mean(u^2) (u the index mapped to [-1, 1]), orthogonal by symmetry, in six passes
    over ``z`` (``polyfit``'s Vandermonde least squares took 5 ms on 65,536 points)."""
    z = np.asarray(z, float)
    n = len(z)
    if n <= 3:  # the quadratic passes through every point
        return np.zeros(n)
    half = (n - 1) / 2.0
    u = np.arange(n, dtype=float)
    u -= half
    u /= half
    b2 = u * u
    b2 -= b2.sum() / n  # the mean (array methods: see _lag1)
    r = z - z.sum() / n
    r -= np.einsum("i,i->", r, u) / np.einsum("i,i->", u, u) * u  # einsum: no BLAS threads (see _lag1)
    r -= np.einsum("i,i->", r, b2) / np.einsum("i,i->", b2, b2) * b2
    return r


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
    z = detrend_quadratic(z)
    d = 0
    while True:
        r1 = _lag1(z)
        delta = r1 / (1.0 + r1)
        if delta < 0.25 or d >= dmax:
            se = 2.0 / (max(1.0 + r1, 1e-3) ** 2 * np.sqrt(max(len(z), 1)))
            return 2.0 - 2.0 * (delta + d), float(se)
        z = np.diff(z)
        d += 1


def round_alpha(a: float, lo: int, hi: int) -> float:
    """``float(np.clip(np.round(a), lo, hi))`` for one exponent (round half to even; NaN stays NaN)
    with Python's scalars: numpy's ufuncs on a scalar cost ~15 us each, ~80 us per tau of ``--taus all``."""
    return a if a != a else float(min(max(round(a), lo), hi))


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
                out[k, c] = round_alpha(noise_id_decimated(z[k][c][:MAX_POINTS_ID], _D[kind]), lo, hi)
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


def _sx(t: np.ndarray, f: float | np.ndarray, alpha: int) -> np.ndarray:
    """sx at ``t`` for the F of each point (``f`` as ``t``, finite) or the F -> inf limit (``f`` = inf)."""
    if np.ndim(f) == 0 and np.isinf(f):
        return _sw(t, alpha + 2)
    if alpha == 1:
        return _sx_flicker(np.asarray(t, float), np.asarray(f, float))
    return f ** 2 * (2.0 * _sw(t, alpha) - _sw(t - 1.0 / f, alpha) - _sw(t + 1.0 / f, alpha))


_SERIES_POWERS = 7  # powers of (h / tau)^2 kept in the flicker-PM expansion (|h / tau| <= 0.1: next term < 1e-19)
_SERIES_GAP = 10.0  # |tau| / h from which the expansion is used


def _u2_logu(u: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(u != 0.0, u * u * np.log(np.abs(u)), 0.0)


def _sx_flicker(t: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Flicker-PM sx = F^2 (2 g(t) - g(t - h) - g(t + h)), g(u) = u^2 ln|u|, h = 1 / F, without the
    F^2 eps cancellation of the direct difference (1e-8 relative at F = 18000): with x = t F,
    sx = 2 ln F + 2 g(x) - g(x - 1) - g(x + 1) for |x| < :data:`_SERIES_GAP`, else
    -2 ln|t| - 3 + sum_p x^(-2p) / (p (p + 1) (2p + 1)) (the series of (1 + u)^2 ln|1 + u|
    + (1 - u)^2 ln|1 - u| in u = 1 / x)."""
    shape = np.broadcast_shapes(np.shape(t), np.shape(f))
    t, f = np.broadcast_arrays(np.atleast_1d(t), np.atleast_1d(f))
    x = t * f
    with np.errstate(divide="ignore", invalid="ignore"):  # x = 0 (a near point) gives inf here
        u2 = x * x
        np.divide(1.0, u2, out=u2)
        series = u2 * (1.0 / (_SERIES_POWERS * (_SERIES_POWERS + 1) * (2 * _SERIES_POWERS + 1)))
        for p in range(_SERIES_POWERS - 1, 0, -1):  # Horner in u^2, in place (the far points are nearly all)
            series += 1.0 / (p * (p + 1) * (2 * p + 1))
            series *= u2
        out = np.abs(t)
        np.log(out, out=out)
        out *= -2.0
        out -= 3.0
        out += series
    near = np.flatnonzero(np.abs(x) < _SERIES_GAP)
    if len(near):
        xn, fn = x.ravel()[near], f.ravel()[near]
        out.ravel()[near] = 2.0 * np.log(fn) + 2.0 * _u2_logu(xn) - _u2_logu(xn - 1.0) - _u2_logu(xn + 1.0)
    return out.reshape(shape)


def _sz(t: np.ndarray, f: float | np.ndarray, alpha: int, d: int) -> np.ndarray:
    """Filtered covariance: the d-th central binomial difference of sx (Greenhall eq. 11)."""
    out = np.zeros_like(np.asarray(t, float))
    for k in range(-d, d + 1):
        out = out + (-1) ** k * comb(2 * d, d + k) * _sx(t + k, f, alpha)
    return out


_CHUNK = 1 << 17  # points of the sums evaluated at once (~1 MB per temporary; 1 << 19 peaked 30 MB higher)


def _sum_terms(j: np.ndarray, s: np.ndarray, f: np.ndarray, alpha: int, d: int) -> np.ndarray:
    """Per grid g (columns: sz(0), sz(J/S), sum 2 sz(i/S)^2, sum 2 i sz(i/S)^2 over i = 1 .. J - 1)
    for the grids of ``j`` terms at spacing 1 / ``s`` and F ``f`` (all finite or all inf); a J
    below 0 (a factor too long for the record) has no inner terms, as the scalar sum."""
    out = np.empty((len(j), 4))
    limit = np.isinf(f[0]) if len(f) else False
    ends = np.cumsum(np.abs(j) + 1)
    g0 = 0
    while g0 < len(j):
        g1 = max(int(np.searchsorted(ends, ends[g0] - (abs(j[g0]) + 1) + _CHUNK, side="right")), g0 + 1)
        counts = np.abs(j[g0:g1]) + 1  # i = 0 .. J
        seg = np.repeat(np.arange(g1 - g0), counts)
        i = (np.arange(len(seg)) - np.repeat(np.cumsum(counts) - counts, counts)) * np.sign(j[g0:g1] + 0.5)[seg]
        t = i / s[g0:g1][seg]
        z = _sz(t, np.inf if limit else f[g0:g1][seg], alpha, d)
        first = np.cumsum(counts) - counts
        inner = (i > 0) & (i < j[g0:g1][seg])
        w = np.where(inner, 2.0 * z ** 2, 0.0)
        out[g0:g1, 0] = z[first]
        out[g0:g1, 1] = z[first + counts - 1]
        out[g0:g1, 2] = np.bincount(seg, w, g1 - g0)
        out[g0:g1, 3] = np.bincount(seg, w * i, g1 - g0)
        g0 = g1
    return out


def _flicker_terms(j: int, s: float, f: np.ndarray, d: int) -> np.ndarray:
    """:func:`_sum_terms` for alpha = 1 (flicker PM) of grids sharing J and S, with F ``f`` (G,) finite.

    Where every |t + k| is at least :data:`_SERIES_GAP` h (h = 1 / F), the expansion of
    :func:`_sx_flicker` makes sz a polynomial in h^2 with coefficients on the shared lattice, and
    sum w sz^2 a quadratic form whose matrix every grid shares; the points near t = 0 .. d are
    evaluated per grid.
    """
    i = np.arange(j + 1)
    t = i / s
    k = np.arange(-d, d + 1)
    coef = np.array([(-1) ** int(v) * comb(2 * d, d + int(v)) for v in k], float)
    tau = t[:, None] + k
    series = (np.abs(tau).min(axis=1) >= _SERIES_GAP / f.min()) & (i > 0) & (i < j)
    ts = tau[series]
    basis = np.empty((len(ts), _SERIES_POWERS + 1))  # sz = basis @ (1, h^2, h^4, ...)
    basis[:, 0] = -2.0 * (np.log(np.abs(ts)) @ coef)
    inv2 = ts ** -2.0
    power = inv2.copy()
    for p in range(1, _SERIES_POWERS + 1):
        basis[:, p] = (power @ coef) / (p * (p + 1) * (2 * p + 1))
        power *= inv2
    h2 = (1.0 / f[:, None]) ** (2 * np.arange(_SERIES_POWERS + 1))
    weights = 2.0 * np.column_stack((np.ones(len(ts)), i[series]))
    out = np.empty((len(f), 4))
    for col, w in ((2, weights[:, 0]), (3, weights[:, 1])):
        out[:, col] = np.einsum("gp,pq,gq->g", h2, basis.T @ (w[:, None] * basis), h2)
    e = np.flatnonzero(~series)  # i = 0 and i = J among them
    z = _sz(np.broadcast_to(t[e], (len(f), len(e))), np.broadcast_to(f[:, None], (len(f), len(e))), 1, d)
    w = np.where((i[e] > 0) & (i[e] < j), 2.0 * z ** 2, 0.0)
    out[:, 0], out[:, 1] = z[:, 0], z[:, -1]
    out[:, 2] += w.sum(axis=1)
    out[:, 3] += w @ i[e]
    return out


def _basic_inv(j: np.ndarray, big_m: np.ndarray, s: np.ndarray, f: np.ndarray, alpha: int, d: int) -> np.ndarray:
    """1 / edf = BasicSum(J, M, S, F) / (M sz(0)^2) of every point; points sharing the grid
    (J, S, F) share its sz values (the rescaled long sums of one record mostly do), flicker-PM
    grids sharing J and S (F = m differs) share the expansion of :func:`_flicker_terms`."""
    key = np.column_stack((j, s, f))
    grids, which = np.unique(key, axis=0, return_inverse=True)
    which = which.ravel()
    terms = np.empty((len(grids), 4))
    for limit in (False, True):
        sel = np.flatnonzero(np.isinf(grids[:, 2]) == limit)
        if alpha == 1 and not limit and len(sel):
            lattices, member = np.unique(grids[sel, :2], axis=0, return_inverse=True)
            member = member.ravel()
            for lat in np.flatnonzero(np.bincount(member) > 1):
                rows = sel[member == lat]
                terms[rows] = _flicker_terms(int(lattices[lat, 0]), lattices[lat, 1], grids[rows, 2], d)
            sel = sel[np.bincount(member)[member] == 1]
        if len(sel):
            terms[sel] = _sum_terms(grids[sel, 0].astype(int), grids[sel, 1], grids[sel, 2], alpha, d)
    z0, zj, sum2, sum2i = terms[which].T
    with np.errstate(divide="ignore", invalid="ignore"):
        basic = z0 ** 2 + (1.0 - j / big_m) * zj ** 2 + (sum2 - sum2i / big_m)
        return basic / (z0 ** 2 * big_m)


_MEMO: dict[tuple, float] = {}
_MEMO_SIZE = 1 << 17  # EDFs kept between calls (the columns of one record share theirs)


def edf_greenhall_many(alpha: np.ndarray | int, d: int, m: np.ndarray | int, n_phase: np.ndarray | int,
                       overlapping: bool = True, modified: bool = False) -> np.ndarray:
    """:func:`edf_greenhall` of every element of ``alpha``, ``m``, ``n_phase`` (broadcast; integers)."""
    al, mm, nn = (a.ravel() for a in np.broadcast_arrays(*(np.asarray(v, dtype=np.int64) for v in (alpha, m, n_phase))))
    shape = np.broadcast_shapes(np.shape(alpha), np.shape(m), np.shape(n_phase))
    keys = [(int(a), d, int(k), int(n), overlapping, modified) for a, k, n in zip(al, mm, nn)]
    first: dict[tuple, int] = {}  # each EDF not yet known, once (the columns of a record share most of theirs)
    for i, key in enumerate(keys):
        if key not in _MEMO and key not in first:
            first[key] = i
    if first:
        todo = np.fromiter(first.values(), np.int64, len(first))
        found = dict(zip(first, _edf_greenhall_new(al[todo], d, mm[todo], nn[todo], overlapping, modified).tolist()))
        if len(_MEMO) + len(found) > _MEMO_SIZE:
            _MEMO.clear()
        _MEMO.update(found)
        out = np.array([found[key] if key in found else _MEMO[key] for key in keys])
    else:
        out = np.array([_MEMO[key] for key in keys])
    return out.reshape(shape)


def _edf_greenhall_new(al: np.ndarray, d: int, mm: np.ndarray, nn: np.ndarray, overlapping: bool,
                       modified: bool) -> np.ndarray:
    m = mm.astype(float)
    f = np.ones(len(m)) if modified else m.copy()
    s = m.copy() if overlapping else np.ones(len(m))
    ell = m / f + m * d
    big_m = 1.0 + np.floor(s * (nn - ell) / m)
    j = np.minimum(big_m, (d + 1) * s)
    out = np.empty(len(m))
    closed = (al == 2) & (np.ceil(big_m / s) > d) & (not modified)
    if closed.any():  # white phase, unmodified: closed form (Greenhall & Riley case 4)
        a0 = comb(4 * d, 2 * d) / comb(2 * d, d) ** 2
        out[closed] = 1.0 / ((a0 - d / 2.0 / (big_m[closed] / s[closed])) / big_m[closed])
    if not modified:  # F = m large: the F -> inf limit avoids cancellation in sx
        f[(al <= 0) & (mm * (d + 1) > J_MAX)] = np.inf
    long = j > J_MAX  # rescale to J_MAX terms, keeping r = M / S and the shape of the sum
    scale = J_MAX / j[long]
    big_m[long], s[long], j[long] = big_m[long] * scale, s[long] * scale, J_MAX
    j = j.astype(np.int64)
    for a in np.unique(al[~closed]):
        sel = np.flatnonzero(~closed & (al == a))
        out[sel] = 1.0 / _basic_inv(j[sel], big_m[sel], s[sel], f[sel], int(a), d)
    return out


def edf_greenhall(alpha: int, d: int, m: int, n_phase: int, overlapping: bool = True,
                  modified: bool = False) -> float:
    """Equivalent degrees of freedom of a d-th difference variance (Greenhall & Riley 2003).

    ``alpha`` noise exponent (integer, alpha + 2d > 1), ``m`` averaging factor, ``n_phase``
    number of phase points; ``overlapping`` (S = m) and ``modified`` (F = 1) choose the
    estimator: oadev (d=2, overlapping), mdev (d=2, overlapping, modified), ohdev (d=3).
    """
    return float(edf_greenhall_many(alpha, d, m, n_phase, overlapping, modified)[()])


def pick_wider(first: np.ndarray, second: np.ndarray, edf) -> np.ndarray:
    """Per element, of the exponents ``first`` and ``second`` the one whose ``edf(alphas, index)``
    (the EDF of those exponents at those elements) is smaller: the wider interval; ``first`` on ties."""
    first, second = np.broadcast_arrays(np.asarray(first, float), np.asarray(second, float))
    out = first.copy()
    idx = np.flatnonzero(first != second)
    if len(idx):
        flat = out.ravel()
        wider = edf(second.ravel()[idx], idx) < edf(first.ravel()[idx], idx)
        flat[idx[wider]] = second.ravel()[idx[wider]]
    return out


# -- intervals -----------------------------------------------------------------------------

def confidence(curve: DeviationCurve, x: np.ndarray | None = None, alpha: np.ndarray | None = None,
               level: float = 0.95, source: str = "data") -> DeviationCI:
    """Chi-squared interval of every point of ``curve`` at two-sided confidence ``level``.

    The noise exponent comes from ``alpha`` (K, C) if given, else is identified from the
    phase ``x`` (C, L) the curve was computed from (:func:`workbench.analysis.allan.phase`);
    NaN exponents (taus too long to identify) are filled as described in the module docstring.
    A column whose deviation is zero at every tau (a constant record) is an AnalysisError naming
    ``source`` (the file or session) and the column.
    """
    flat = ~np.any(curve.dev > 0, axis=0)
    if flat.any():
        col = curve.columns[int(np.argmax(flat))] if curve.columns else str(int(np.argmax(flat)))
        raise AnalysisError(f"{source}: column {col}: the deviation is zero at every tau: a constant record has no noise "
                            "to characterise (a stuck or disconnected channel?)")
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
    """EDF (K, C) of every point of ``curve`` for the exponents ``alpha`` (K, C)."""
    return _edf_at(curve, alpha, np.broadcast_to(curve.m[:, None], alpha.shape))


def _edf_at(curve: DeviationCurve, alpha: np.ndarray, m: np.ndarray) -> np.ndarray:
    return edf_greenhall_many(alpha.astype(np.int64), _D[curve.kind], m, curve.n_samples + 1, True,
                              curve.kind == "mdev")


def _fill_short(curve: DeviationCurve, alpha: np.ndarray) -> np.ndarray:
    """Fill the taus too long to identify: of the exponent carried from the last identified
    tau and the one from the curve's local slope, take the one giving fewer degrees of
    freedom (the wider, conservative interval)."""
    slope = alpha_from_slope(curve)
    known = np.isfinite(alpha)
    rows = np.arange(len(curve.m))[:, None]
    carried = np.maximum.accumulate(np.where(known, rows, -1), axis=0)
    cols = np.arange(alpha.shape[1])
    last = np.where(carried >= 0, alpha[np.maximum(carried, 0), cols], slope[0])
    out = alpha.copy()
    k, c = np.nonzero(~known)
    out[k, c] = pick_wider(last[k, c], slope[k, c], lambda a, i: _edf_at(curve, a, curve.m[k[i]]))
    return out
