"""The frequency-stability family: one signature for every Allan-type statistic (NIST SP 1065).

``stability(data, rate, stat, data_type, taus)`` computes, for one channel, the deviation
``stat`` of :data:`STATS` at averaging factors m (tau = m / rate):

* ``adev`` / ``oadev``: non-overlapping / overlapping Allan (SP 1065 eq. 7, 11);
* ``mdev``, ``tdev``: modified Allan and time deviation tau mdev / sqrt(3) (eq. 14, 16);
* ``hdev`` / ``ohdev``: non-overlapping / overlapping Hadamard (eq. 17, 18);
* ``totdev``: total deviation of the phase reflected at both ends (eq. 25);
* ``mtotdev``, ``ttotdev``: modified total (eq. 27; subsequences of 3m points, half-average
  detrended, extended by uninverted even reflection) and time total tau mtotdev / sqrt(3);
* ``htotdev``: Hadamard total (the same construction on frequency; ohdev at m = 1, as Stable32);
* ``theo1``: Theo1 at tau = 0.75 m (m even; eq. 30); ``theoh`` TheoH: oadev up to the
  largest tau below 10 % of the record, bias-removed Theo1 (matched to oadev) beyond;
* ``mtie``: maximum over windows of m + 1 points of max - min phase; ``tierms``: rms of
  x[i+m] - x[i].

``data_type`` ``"freq"`` (rate samples, e.g. rad/s; the phase is ``dt cumsum(y - mean)`` with
x_0 = 0) or ``"phase"`` (time error / angle, e.g. rad). The deviations are in the frequency
unit (rate unit for ``freq`` input, phase unit per second for ``phase`` input), tdev, ttotdev,
mtie and tierms in the phase unit.

Gaps: NaN samples mark missing data (Stable32's convention). For frequency data a difference
is skipped when any sample of the frequency averages it uses is missing; for phase data when
any phase point it uses is missing (for ``mdev`` / ``tdev`` any point of its windows). The
counts ``n`` and the degrees of freedom follow the pairs actually used. The total and Theo
statistics and MTIE need a gap-free record.

Public: :data:`STATS`, :class:`Stability`, :func:`stability`, :func:`factors`, :func:`to_phase`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.errors import AnalysisError

STATS = ("adev", "oadev", "mdev", "tdev", "hdev", "ohdev", "totdev", "mtotdev", "ttotdev", "htotdev",
         "theo1", "theoh", "mtie", "tierms")
GAP_FREE = ("totdev", "mtotdev", "ttotdev", "htotdev", "theo1", "theoh", "mtie")
MIN_PHASE_POINTS = {"htotdev": 4}  # phase points below which a statistic has no term (default 3)
# largest m as a fraction of the phase points: a statistic needs at least one full difference
_SPAN = {"adev": 2, "oadev": 2, "mdev": 3, "tdev": 3, "hdev": 3, "ohdev": 3, "totdev": 1, "mtotdev": 3,
         "ttotdev": 3, "htotdev": 3, "theo1": 1, "theoh": 1, "mtie": 1, "tierms": 1}
# Stable32's stop ratios: automatic tau grids end at m = (L - 1) / ratio (L phase points)
STOP = {"adev": 5, "oadev": 4, "mdev": 4, "tdev": 4, "hdev": 5, "ohdev": 4, "totdev": 2, "mtotdev": 3,
        "ttotdev": 3, "htotdev": 3, "theo1": 1, "theoh": 1, "mtie": 1, "tierms": 4}
THEO_BIAS_TAU = 0.1  # TheoH switches from oadev to bias-removed Theo1 above this fraction of the record


@dataclass(frozen=True)
class Stability:
    """One channel's deviation versus tau.

    ``tau`` (K,) s (Theo1: 0.75 m / rate); ``m`` (K,) averaging factors; ``dev`` (K,) the deviation
    (unit in the module docstring); ``n`` (K,) number of terms summed (pairs used); ``n_phase``
    phase points of the record; ``stat``, ``rate`` Hz, ``data_type``.
    """

    stat: str
    tau: np.ndarray
    m: np.ndarray
    dev: np.ndarray
    n: np.ndarray
    rate: float
    n_phase: int
    data_type: str


def to_phase(data: np.ndarray, rate: float, data_type: str) -> np.ndarray:
    """Phase (L,) of a 1-D record: ``freq`` -> x_0 = 0, x_k = dt cumsum(y - mean) (NaN kept where a
    gap makes the point unknown relative to the first), ``phase`` -> as given (float copy)."""
    d = np.asarray(data, float).ravel()
    if data_type == "phase":
        return d
    if data_type != "freq":
        raise AnalysisError(f"data type {data_type!r} is not freq or phase")
    bad = ~np.isfinite(d)
    y = np.where(bad, 0.0, d - (np.mean(d[~bad]) if (~bad).any() else 0.0))
    x = np.empty(len(d) + 1)
    x[0] = 0.0
    np.cumsum(y, out=x[1:])
    x[1:] *= 1.0 / rate
    return x


def factors(n_phase: int, taus: str | np.ndarray | list, rate: float, stat: str) -> np.ndarray:
    """Averaging factors m (int64, sorted, unique) of ``stat`` for ``n_phase`` phase points.

    ``taus``: ``"octave"`` (1, 2, 4, ...), ``"decade"`` (1, 2, 4, 10, 20, 40, ...), ``"all"``
    (every m), ending at Stable32's stop ratio (:data:`STOP`), or taus in s (rounded to multiples
    of 1 / rate), kept while the statistic has a complete difference. Theo1 keeps even m (its
    tau is 0.75 m / rate: given taus are matched on that).
    """
    top = max((n_phase - 1) // _SPAN[stat], 1)
    if isinstance(taus, str):
        top = max(min(top, (n_phase - 1) // STOP[stat]), 1)
        if taus == "octave":
            m = 2 ** np.arange(int(np.log2(max(n_phase, 1))) + 1)
        elif taus == "decade":
            m = np.array([f * 10 ** k for k in range(int(np.log10(max(n_phase, 1))) + 1) for f in (1, 2, 4)])
        elif taus == "all":
            m = np.arange(1, top + 1)
        else:
            raise AnalysisError(f"taus {taus!r}: expected octave, decade, all or a list of taus in s")
    else:
        scale = 0.75 if stat == "theo1" else 1.0
        m = np.round(np.asarray(taus, float).ravel() * rate / scale)
    m = np.unique(m[(m >= 1) & (m <= top)]).astype(np.int64)
    if stat in ("theo1",):
        m = m[m % 2 == 0]
    return m


def stability(data: np.ndarray, rate: float = 1.0, stat: str = "oadev", data_type: str = "freq",
              taus: str | np.ndarray | list = "octave") -> Stability:
    """Deviation ``stat`` of one channel ``data`` (N,) at ``rate`` Hz, taus as :func:`factors`.

    Any length the statistic allows (a few points: the NBS 10-point set runs here). Raises
    :class:`workbench.errors.AnalysisError` for unknown names, bad rates and records too short.
    """
    if stat not in STATS:
        raise AnalysisError(f"statistic {stat!r} is not one of {', '.join(STATS)}")
    if not (np.isfinite(rate) and rate > 0):
        raise AnalysisError(f"sample rate {rate!r} Hz must be positive")
    x = to_phase(data, float(rate), data_type)
    fewest = MIN_PHASE_POINTS.get(stat, 3)  # one second difference (HTOTDEV: one third difference)
    if len(x) < fewest:
        raise AnalysisError(f"{stat}: {len(np.asarray(data).ravel())} {data_type} point(s): too few "
                            f"(at least {fewest - (data_type == 'freq')})")
    gaps = ~np.isfinite(np.asarray(data, float).ravel())
    if gaps.any() and stat in GAP_FREE:
        raise AnalysisError(f"{stat}: {int(gaps.sum())} missing sample(s): {stat} needs a gap-free record "
                            "(cut it, or use a statistic that skips gaps)")
    if stat == "theoh":
        return _theoh(x, float(rate), data_type, taus)
    m = factors(len(x), taus, float(rate), stat)
    if len(m) == 0:
        raise AnalysisError(f"{stat}: no averaging factor fits {len(np.asarray(data).ravel())} {data_type} points")
    bad_y = gaps if data_type == "freq" else None
    dev, n = _compute(stat, x, m, float(rate), bad_y)
    keep = n > 0
    if not keep.any():
        raise AnalysisError(f"{stat}: no averaging factor leaves a complete difference in "
                            f"{len(np.asarray(data).ravel())} {data_type} points")
    tau = m / float(rate) * (0.75 if stat == "theo1" else 1.0)
    return Stability(stat, tau[keep], m[keep], dev[keep], n[keep], float(rate), len(x), data_type)


# -- the statistics ---------------------------------------------------------------------------

def _valid_spans(x: np.ndarray, bad_y: np.ndarray | None, starts: np.ndarray, span: int,
                 points: tuple[int, ...] | None) -> np.ndarray:
    """Which terms starting at ``starts`` are free of gaps (see the module docstring)."""
    if bad_y is not None:  # frequency data: no missing sample in y[start : start + span]
        c = np.concatenate(([0], np.cumsum(bad_y)))
        return c[starts + span] - c[starts] == 0
    bad_x = ~np.isfinite(x)
    if not bad_x.any():
        return np.ones(len(starts), bool)
    if points is None:  # every point of the windows
        c = np.concatenate(([0], np.cumsum(bad_x)))
        return c[starts + span + 1] - c[starts] == 0
    ok = np.ones(len(starts), bool)
    for p in points:
        ok &= ~bad_x[starts + p]
    return ok


def _compute(stat: str, x: np.ndarray, m: np.ndarray, rate: float, bad_y: np.ndarray | None):
    tau0 = 1.0 / rate
    devs = np.full(len(m), np.nan)
    ns = np.zeros(len(m), np.int64)
    if stat in ("totdev", "mtotdev", "ttotdev", "htotdev", "theo1", "mtie"):
        for k, mk in enumerate(m):
            devs[k], ns[k] = _gap_free(stat, x, int(mk), tau0)
        return devs, ns
    gap_free = (bad_y is None or not bad_y.any()) and bool(np.isfinite(x).all())
    if gap_free and stat in _ALL_LAGS:
        return _all_lags(stat, x, m, tau0)
    xz = np.where(np.isfinite(x), x, 0.0)
    cs = np.concatenate(([0.0], np.cumsum(xz))) if stat in ("mdev", "tdev") else None
    for k, mk in enumerate(m):
        mk = int(mk)
        tau = mk * tau0
        if stat in ("adev", "oadev", "hdev", "ohdev"):
            order = 2 if stat in ("adev", "oadev") else 3
            stride = mk if stat in ("adev", "hdev") else 1
            starts = np.arange(0, len(x) - order * mk, stride)
            coef = (1.0, -2.0, 1.0) if order == 2 else (-1.0, 3.0, -3.0, 1.0)
            d = sum(c * xz[starts + j * mk] for j, c in enumerate(coef))
            ok = _valid_spans(x, bad_y, starts, order * mk, tuple(j * mk for j in range(order + 1)))
            ns[k] = int(ok.sum())
            devs[k] = np.sqrt(np.sum(d[ok] ** 2) / ((2.0 if order == 2 else 6.0) * tau ** 2 * ns[k])) \
                if ns[k] else np.nan
        elif stat in ("mdev", "tdev"):
            starts = np.arange(0, len(x) - 3 * mk + 1)
            d = (cs[starts + 3 * mk] - 3.0 * cs[starts + 2 * mk] + 3.0 * cs[starts + mk] - cs[starts])
            ok = _valid_spans(x, bad_y, starts, 3 * mk - 1, None)
            ns[k] = int(ok.sum())
            if ns[k]:
                v = np.sum(d[ok] ** 2) / (2.0 * mk ** 2 * tau ** 2 * ns[k])
                devs[k] = np.sqrt(v) * (tau / np.sqrt(3.0) if stat == "tdev" else 1.0)
        elif stat == "tierms":
            starts = np.arange(0, len(x) - mk)
            d = xz[starts + mk] - xz[starts]
            ok = _valid_spans(x, bad_y, starts, mk, (0, mk))
            ns[k] = int(ok.sum())
            devs[k] = np.sqrt(np.mean(d[ok] ** 2)) if ns[k] else np.nan
    return devs, ns


_ALL_LAGS = {"oadev": "oadev", "ohdev": "ohdev", "mdev": "mdev", "tdev": "mdev"}  # stat -> kind of the kernel


def _all_lags(stat: str, x: np.ndarray, m: np.ndarray, tau0: float) -> tuple[np.ndarray, np.ndarray]:
    """A gap-free record's overlapping ADEV / HDEV, MDEV / TDEV at every m in one call of
    :func:`workbench.analysis.allan.squared_sums` (cache-blocked compiled kernels for long records:
    the sums of the per-lag formulas of :func:`_compute`, grouped differently)."""
    from workbench.analysis import allan

    kind = _ALL_LAGS[stat]
    n = np.maximum(len(x) - allan.ORDER[kind] * m + (1 if kind == "mdev" else 0), 0)
    dev = np.full(len(m), np.nan)
    ok = n > 0
    dev[ok] = allan.normalise(kind, allan.squared_sums(x[None, :], m[ok], kind), n[ok], m[ok], 1.0 / tau0)[:, 0]
    if stat == "tdev":
        dev = dev * m * tau0 / np.sqrt(3.0)
    return dev, n.astype(np.int64)


def _gap_free(stat: str, x: np.ndarray, m: int, tau0: float) -> tuple[float, int]:
    """The statistics that need every point (reflections, subsequences, windows)."""
    n_x = len(x)
    tau = m * tau0
    if stat == "mtie":
        from numpy.lib.stride_tricks import sliding_window_view

        w = sliding_window_view(x, m + 1)
        return float(np.max(w.max(axis=1) - w.min(axis=1))), n_x - m
    from workbench.analysis import stability_kernels as kern  # numba loads for these statistics only

    if stat == "totdev":
        return float(np.sqrt(kern.totdev_sum(x, m) / (2.0 * tau ** 2 * (n_x - 2)))), n_x - 2
    if stat in ("mtotdev", "ttotdev"):
        if n_x - 3 * m + 1 < 1:
            return float("nan"), 0
        v = kern.mtot_sum(x, m, False) / (2.0 * tau ** 2 * (n_x - 3 * m + 1))
        dev = np.sqrt(v) * (tau / np.sqrt(3.0) if stat == "ttotdev" else 1.0)
        return float(dev), n_x - 3 * m + 1
    if stat == "htotdev":
        y = np.diff(x) / tau0
        if m == 1:
            d = x[3:] - 3.0 * x[2:-1] + 3.0 * x[1:-2] - x[:-3]
            return float(np.sqrt(np.sum(d * d) / (6.0 * tau ** 2 * len(d)))), len(d)
        if len(y) - 3 * m + 1 < 1:
            return float("nan"), 0
        return float(np.sqrt(kern.mtot_sum(y, m, True) / (len(y) - 3 * m + 1))), len(y) - 3 * m + 1
    if stat == "theo1":
        if n_x - m < 1:
            return float("nan"), 0
        s = kern.theo1_sum(x, m)
        return float(np.sqrt(s / (0.75 * (n_x - m) * tau ** 2))), (n_x - m) * m // 2
    raise AssertionError(stat)


def _theoh(x: np.ndarray, rate: float, data_type: str, taus) -> Stability:
    """TheoH: oadev for tau <= :data:`THEO_BIAS_TAU` of the record, bias-removed Theo1 above.

    The Theo1 bias is the ratio of the mean oadev to the mean Theo1 over the taus where both
    exist between 10 % and 30 % of the record... (Howe's TheoBR uses the average ratio over
    the Theo1 range; here the overlap band keeps it cheap).
    """
    n_phase = len(x)
    span = (n_phase - 1) / rate
    oa = stability(x, rate, "oadev", "phase", taus)
    th = stability(x, rate, "theo1", "phase", taus if not isinstance(taus, str) else "all")
    band = (oa.tau >= THEO_BIAS_TAU * span / 4) & (oa.tau <= THEO_BIAS_TAU * span)
    ratio = 1.0
    if band.any():
        t_match = np.interp(oa.tau[band], th.tau, th.dev, left=np.nan, right=np.nan)
        ok = np.isfinite(t_match)
        if ok.any():
            ratio = float(np.mean(oa.dev[band][ok] ** 2) / np.mean(t_match[ok] ** 2))
    lo = oa.tau <= THEO_BIAS_TAU * span
    hi_m = factors(n_phase, taus, rate, "theo1")
    hi_sel = np.isin(th.m, hi_m) & (th.tau > THEO_BIAS_TAU * span)
    tau = np.concatenate((oa.tau[lo], th.tau[hi_sel]))
    return Stability("theoh", tau, np.concatenate((oa.m[lo], th.m[hi_sel])),
                     np.concatenate((oa.dev[lo], th.dev[hi_sel] * np.sqrt(ratio))),
                     np.concatenate((oa.n[lo], th.n[hi_sel])), rate, n_phase, data_type)
