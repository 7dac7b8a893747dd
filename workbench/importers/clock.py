"""Sampling instants from host arrival time stamps: a sample clock fitted under the stamps.

A host that reads a sensor stamps each sample when it *arrives*: ``a_i = t_i + L_i`` with
``t_i`` the sampling instant and ``L_i >= 0`` the latency (buffering, bursts, transport). The
sensor samples on its own clock, ``t_i = f(k_i)`` for sample number ``k_i`` with ``f`` a
slowly drifting line. Since every latency is non-negative, ``f`` is the *lower envelope* of
the stamps: the continuous piecewise-linear function (knots every ``knot_s``, which follows
drift) that lies under every ``(k_i, a_i)`` and is as high as possible (the sum of the
latencies is smallest). This is a linear programme (one constraint per sample; only the lower
convex hull of the points between two knots can be active, so only those are passed to the
solver). The smallest latency is common to all samples and cannot be seen in the stamps:
the instants are the true ones plus that constant.

Lost samples (the recorder paused or dropped data) show as a step up of the envelope: after
the loss every sample is late by the missing time. A step of more than :data:`GAP_PERIODS`
sample periods (and over :data:`GAP_MIN_S`) in the running minimum latency becomes a gap; its
length comes from clock lines under the stamps on either side (5 s each, with the median
period of the knot intervals as slope, so only their offsets are fitted), and the clock is
fitted again with the sample numbers shifted.

Public: :func:`fit_arrival_clock` -> :class:`ClockFit`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog
from scipy.sparse import csr_matrix
from scipy.spatial import ConvexHull, QhullError

from workbench.errors import ImportProfileError

GAP_PERIODS = 2.5  # an envelope step of more periods than this may be lost samples (the session's gap rule) ...
GAP_MIN_S = 0.1  # ... when it is also longer than this: shorter steps are the host's irregular reading, not losses
KNOT_S = 5.0  # s between knots of the clock: drift slower than this is followed


@dataclass(frozen=True)
class ClockFit:
    """A sample clock fitted to arrival stamps (all times in s on the host clock).

    ``instants`` (N,) reconstructed sampling instants; ``sample_number`` (N,) the fitted
    ``k_i`` (consecutive except across ``gaps``); ``latency`` (N,) arrival minus instant (>= 0);
    ``rate_hz`` the mean rate of the fitted clock; ``drift_ppm`` the spread (max - min) of the
    rate over the knot intervals relative to the mean (resolved to about
    ``drift_resolution_ppm``: twice the instants' uncertainty over a knot interval); ``envelope_noise_s`` the rms of the
    per-second minimum latency about the envelope (how well the stamps pin the clock: the
    reconstructed instants are uncertain by about this much); ``gaps`` ``(row, lost samples,
    seconds)`` per gap, ``row`` the first sample after it.
    """

    instants: np.ndarray
    sample_number: np.ndarray
    latency: np.ndarray
    rate_hz: float
    drift_ppm: float
    envelope_noise_s: float
    gaps: tuple[tuple[int, int, float], ...]
    knot_s: float = KNOT_S

    @property
    def drift_resolution_ppm(self) -> float:
        """The smallest rate change ``drift_ppm`` resolves, ppm."""
        return 2e6 * self.envelope_noise_s / self.knot_s

    def latency_percentiles_ms(self) -> tuple[float, float, float]:
        """Median, 99th percentile and largest latency above the fitted clock, ms."""
        p50, p99 = np.percentile(self.latency, [50, 99])
        return 1e3 * float(p50), 1e3 * float(p99), 1e3 * float(self.latency.max())


def _hull_vertices(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Indices of the convex hull's vertices of the points (qhull); all points when degenerate.

    A superset of the lower hull: the upper vertices are valid, non-binding constraints."""
    if len(x) < 4:
        return np.arange(len(x))
    try:
        return ConvexHull(np.c_[x - x[0], (y - y.min()) * (x[-1] - x[0] + 1) / (np.ptp(y) + 1e-300)]).vertices
    except QhullError:
        return np.arange(len(x))


def _hat(k: np.ndarray, knots: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Piecewise-linear basis: for each k its left knot index j and the weights of knots j, j+1."""
    j = np.clip(np.searchsorted(knots, k, side="right") - 1, 0, len(knots) - 2)
    w = (k - knots[j]) / (knots[j + 1] - knots[j])
    return j, 1.0 - w, w


def _envelope(k: np.ndarray, a: np.ndarray, period: float, knot_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Knots (in sample numbers) and knot values (s) of the highest continuous piecewise line under (k, a)."""
    # knots on samples (so no interval is empty, even across a long gap), about knot_s apart
    step = max(1, int(round(knot_s / period)))
    marks = np.searchsorted(k, np.arange(k[0], k[-1], step))
    knots = np.unique(np.r_[k[marks], k[-1]]).astype(float)
    if len(knots) > 2 and knots[-1] - knots[-2] < step / 2:
        knots = np.delete(knots, -2)  # no short last interval
    n_int = len(knots) - 1
    # detrend by the nominal period so the hull and the LP are well scaled
    y = a - k * period
    j_all = np.clip(np.searchsorted(knots, k, side="right") - 1, 0, n_int - 1)
    rows = []
    bounds = np.searchsorted(j_all, np.arange(n_int + 1))  # j_all is sorted: interval j is rows bounds[j]..
    for j in range(n_int):
        sel = np.arange(bounds[j], bounds[j + 1])
        rows.append(sel[_hull_vertices(k[sel].astype(float), y[sel])])
    active = np.unique(np.concatenate(rows))
    j, w0, w1 = _hat(k[active].astype(float), knots)
    n_act = len(active)
    a_ub = csr_matrix((np.r_[w0, w1], (np.r_[np.arange(n_act), np.arange(n_act)], np.r_[j, j + 1])),
                      shape=(n_act, n_int + 1))
    ja, v0, v1 = _hat(k.astype(float), knots)
    c = -(np.bincount(ja, v0, n_int + 1) + np.bincount(ja + 1, v1, n_int + 1))
    res = linprog(c / len(k), A_ub=a_ub, b_ub=y[active], bounds=[(None, None)] * (n_int + 1), method="highs")
    if res.status != 0:  # pragma: no cover - the LP is always feasible and bounded for >= 2 distinct points
        raise ImportProfileError(f"arrival clock: the envelope fit failed ({res.message})")
    return knots, res.x + knots * period


def _evaluate(k: np.ndarray, knots: np.ndarray, values: np.ndarray) -> np.ndarray:
    j, w0, w1 = _hat(k.astype(float), knots)
    return w0 * values[j] + w1 * values[j + 1]


def _running_min_steps(latency: np.ndarray, candidates: np.ndarray, width: int) -> np.ndarray:
    """Step of the minimum latency at each candidate row: min over the next ``width`` minus the previous."""
    cs = np.empty(len(candidates))
    for n, i in enumerate(candidates):
        cs[n] = latency[i:i + width].min() - latency[max(0, i - width):i].min()
    return cs


def _lost_samples(a: np.ndarray, row: int, width: int, period: float) -> int:
    """Samples lost before ``row``: the clock lines of slope ``period`` under the stamps on either side
    (``width`` samples each), extrapolated to the pause, differ by the missing time."""
    lo, hi = max(0, row - width), min(len(a), row + width)
    if row - lo < 2 or hi - row < 2:
        return 0
    k = np.arange(lo, hi)
    y = a[lo:hi] - period * k
    t_last = float(y[:row - lo].min()) + period * (row - 1)  # instant of the last sample before the pause
    t_first = float(y[row - lo:].min()) + period * row  # instant of the first sample after it
    return max(0, int(round((t_first - t_last) / period)) - 1)


def fit_arrival_clock(arrival: np.ndarray, nominal_rate_hz: float | None, where: str,
                      knot_s: float = KNOT_S) -> ClockFit:
    """Fit the sample clock to arrival stamps ``arrival`` (N,) s (see the module docstring).

    ``nominal_rate_hz`` is the sensor's declared rate (None: the mean rate of the stamps); it
    only starts the fit. ``where`` names the stream in errors.
    """
    a = np.asarray(arrival, float)
    if len(a) < 4:
        raise ImportProfileError(f"{where}: arrival stamps: need at least 4 samples, got {len(a)}")
    if np.any(np.diff(a) < 0):
        row = int(np.argmax(np.diff(a) < 0)) + 1
        raise ImportProfileError(f"{where}: arrival stamps go back in time at row {row} ({float(a[row])!r} s; "
                                 f"row {row - 1}: {float(a[row - 1])!r} s)")
    period = 1.0 / nominal_rate_hz if nominal_rate_hz else (a[-1] - a[0]) / (len(a) - 1)
    offsets = np.zeros(len(a), dtype=np.int64)  # lost samples before each row
    width = max(20, int(round(1.0 / period)))  # one second of samples for the running minimum
    for _ in range(256):  # one gap per pass, the largest step first
        k = np.arange(len(a)) + offsets
        knots, values = _envelope(k, a, period, knot_s)
        period = (values[-1] - values[0]) / (knots[-1] - knots[0])
        pauses = np.flatnonzero(np.diff(a) > GAP_PERIODS * period) + 1
        if not len(pauses):
            break
        # steps of the latency above a straight clock (the envelope would absorb a step into a ramp)
        steps = _running_min_steps(a - k * period, pauses, width)
        best = int(np.argmax(steps))
        if steps[best] <= max(GAP_PERIODS * period, GAP_MIN_S) / 2:
            break
        # the gap is at the earliest pause near the step from which the two clocks differ by it
        side = int(round(knot_s / period))
        near = pauses[(np.abs(pauses - pauses[best]) <= width) & (pauses >= width) & (pauses <= len(a) - width)]
        if not len(near):  # within a second of an end: too few stamps on one side to tell a loss
            break
        # the slope: the median of the knot intervals' periods (the few next to a loss are off)
        typical = float(np.median(np.diff(values) / np.diff(knots)))
        lost = np.array([_lost_samples(a, r, side, typical) for r in near])
        if lost.max() * period <= max(GAP_PERIODS * period, GAP_MIN_S):
            break
        agree = lost >= lost.max() - 1
        at = int(np.argmax(agree))  # the earliest: the pauses after the loss see it too
        offsets[near[at]:] += int(np.round(np.median(lost[agree])))
    k = np.arange(len(a)) + offsets
    instants = _evaluate(k, knots, values)
    lat = a - instants
    rates = np.diff(knots) / np.diff(values)
    mean_rate = (knots[-1] - knots[0]) / (values[-1] - values[0])
    drift = float((rates.max() - rates.min()) / mean_rate * 1e6) if len(rates) > 1 else 0.0
    per_s = [lat[i:i + width].min() for i in range(0, len(a) - width + 1, width)] or [lat.min()]
    noise = float(np.sqrt(np.mean(np.square(per_s))))
    dk = np.diff(k)
    gaps = tuple((int(i + 1), int(dk[i] - 1), float((dk[i] - 1) / mean_rate)) for i in np.flatnonzero(dk > 1))
    return ClockFit(instants, k, lat, float(mean_rate), drift, noise, gaps, knot_s)
