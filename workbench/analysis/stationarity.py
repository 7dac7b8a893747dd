"""Stationarity detection: which stretches of a record the unit was still.

Paper 001 (shared/seeds/001_...) sec. 3.1.1, eq. 41-45, detects a static platform from the
moving average of the gyro output (eq. 41-42) and the acceleration (eq. 44-45) against
thresholds. Here both sensors enter one generalised likelihood-ratio test over a sliding window
of ``N`` samples, with the thresholds derived from the noise instead of chosen by hand:

    T = sum_axes sum_k (a_k - mean a)^2 / s_a^2  +  sum_axes sum_k (w_k - mean w)^2 / s_w^2
        + N |mean w - b_w|^2 / s_w^2                                    (second pass only)

where ``s_a``, ``s_w`` are the per-sample white-noise sigmas (from the grade, or estimated from
the quietest windows of the record, :func:`estimate_sigma`, then refined as the mean window
variance over the first pass's still stretches) and ``b_w`` the gyro bias found on
the stretches of the first pass (their median, then the mean of the stretches the full test
keeps). The mean term counts only what exceeds the Earth rate plus ``rate_tolerance`` (default
0.2 °/s, twice a MEMS gyro's typical g-sensitivity of 0.1 °/s/g: the bias moves by that much
between orientations); a steady turn slower than that about the vertical is not seen (any turn
about another axis still is, through the accelerometer). For a still unit, the first two sums are chi-square with ``6 (N - 1)`` degrees of
freedom (the window means of eq. 41 absorb the unknown bias and gravity direction); the mean
term adds 3. The threshold is that distribution's ``1 - false_alarm`` quantile: a window of a
still unit is called moving with probability ``false_alarm``. The variance terms see any change of
the gravity direction or rate within the window; the mean term (eq. 41-42) sees a steady
rotation (about the vertical, where the accelerometer sees nothing).

A sample is still when the window centred on it passes; runs shorter than ``min_still_s`` are
dropped. Public: :class:`Stillness`, :func:`detect`, :func:`estimate_sigma`,
:func:`moving_summary`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import gammaincinv

from workbench.earth import EARTH_RATE
from workbench.errors import AnalysisError

QUIET_QUANTILE = 0.1  # fraction of windows taken as the quietest when the noise is estimated


def _chi2_ppf(q, dof):
    """Quantile ``q`` of the chi-squared law with ``dof`` degrees of freedom: what scipy.stats.chi2.ppf
    computes (the same special function), without importing scipy.stats (0.3-0.5 s at start-up)."""
    return 2.0 * gammaincinv(np.asarray(dof, float) / 2, q)


@dataclass(frozen=True)
class Stillness:
    """The still stretches of a record and how they were found.

    ``still`` (N,) bool per sample; ``stretches`` [(start, stop)] sample index ranges (stop
    exclusive); ``statistic`` (N,) the test statistic of the window centred on each sample divided
    by its degrees of freedom (about 1 when still); ``threshold`` the same scale's limit;
    ``window`` samples; ``gyro_sigma`` rad/s and ``accel_sigma`` m/s^2 (3,) per-sample noise used,
    ``noise_source`` ``"given"`` or ``"estimated"``; ``gyro_bias`` (3,) rad/s the mean gyro output
    over the first pass's still stretches (NaN if none).
    """

    still: np.ndarray
    stretches: list[tuple[int, int]]
    statistic: np.ndarray
    threshold: float
    window: int
    gyro_sigma: np.ndarray
    accel_sigma: np.ndarray
    noise_source: str
    gyro_bias: np.ndarray
    false_alarm: float

    @property
    def still_fraction(self) -> float:
        """Fraction of the samples that are still."""
        return float(self.still.mean()) if len(self.still) else 0.0

    def to_dict(self) -> dict:
        """JSON-ready summary (SI)."""
        return {"window_samples": self.window, "threshold": self.threshold, "false_alarm": self.false_alarm,
                "noise_source": self.noise_source, "gyro_sigma_rad_s": self.gyro_sigma.tolist(),
                "accel_sigma_m_s2": self.accel_sigma.tolist(), "still_fraction": self.still_fraction,
                "stretches": [list(s) for s in self.stretches]}


def _window_sums(x: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Sum of squared deviations from the window mean (W, C) and window means (W, C), windows x[i:i+n]."""
    x = x - x.mean(axis=0)  # conditioning of the running sums
    c1 = np.vstack([np.zeros(x.shape[1]), np.cumsum(x, axis=0)])
    c2 = np.vstack([np.zeros(x.shape[1]), np.cumsum(x * x, axis=0)])
    s1, s2 = c1[n:] - c1[:-n], c2[n:] - c2[:-n]
    return np.maximum(s2 - s1 * s1 / n, 0.0), s1 / n


def _floor(x: np.ndarray) -> np.ndarray:
    """Per-axis lower bound of a sigma: the rounding noise of the output step (smallest change / sqrt 12)."""
    d = np.abs(np.diff(x, axis=0))
    out = np.empty(x.shape[1])
    for i in range(x.shape[1]):
        nz = d[:, i][d[:, i] > 0]
        out[i] = (nz.min() if nz.size else 1e-12) / np.sqrt(12.0)
    return out


def estimate_sigma(x: np.ndarray, window: int) -> np.ndarray:
    """Per-sample white-noise sigma (C,) of samples ``x`` (N, C), in their unit, from the quietest windows.

    Non-overlapping windows of ``window`` samples give per-axis variances; their
    :data:`QUIET_QUANTILE` quantile, divided by the same quantile of a chi-square with
    ``window - 1`` degrees of freedom (per degree), is unbiased when at least that fraction of
    the record is still and too small otherwise (then the detector is stricter, never laxer).
    """
    x = np.asarray(x, float)
    m = len(x) // window
    if m < 1:
        raise AnalysisError(f"stationarity: {len(x)} samples, fewer than one window of {window}")
    blocks = x[:m * window].reshape(m, window, x.shape[1])
    var = blocks.var(axis=1, ddof=1)
    q = np.quantile(var, QUIET_QUANTILE, axis=0)
    dof = window - 1
    return np.maximum(np.sqrt(q / (_chi2_ppf(QUIET_QUANTILE, dof) / dof)), _floor(x))


def _runs(mask: np.ndarray, min_len: int) -> list[tuple[int, int]]:
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2]) if b - a >= min_len]


def _centred(stat_w: np.ndarray, n_samples: int, n: int) -> np.ndarray:
    """Per-sample statistic of the window centred on each sample (edges take the nearest window)."""
    idx = np.clip(np.arange(n_samples) - n // 2, 0, len(stat_w) - 1)
    return stat_w[idx]


def detect(gyro: np.ndarray, accel: np.ndarray, sample_rate_hz: float, gyro_sigma=None, accel_sigma=None,
           window_s: float = 0.5, min_still_s: float = 1.0, false_alarm: float = 1e-3,
           rate_tolerance: float = float(np.radians(0.2))) -> Stillness:
    """Still stretches of a record (see the module docstring).

    Parameters
    ----------
    gyro : (N, 3) rad/s, body frame; accel : (N, 3) m/s^2 specific force, body frame
    sample_rate_hz : Hz
    gyro_sigma, accel_sigma : per-sample white-noise sigma, rad/s and m/s^2 (scalar or (3,));
        None estimates them from the record (:func:`estimate_sigma`)
    window_s : s, the sliding window; min_still_s : s, shortest still stretch kept
    false_alarm : probability that a window of a still unit is called moving
    rate_tolerance : rad/s, change of the gyro bias between still orientations the mean term allows
    """
    gyro, accel = np.asarray(gyro, float), np.asarray(accel, float)
    if gyro.shape != accel.shape or gyro.ndim != 2 or gyro.shape[1] != 3:
        raise AnalysisError(f"stationarity: gyro {gyro.shape} and accel {accel.shape} must both be (N, 3)")
    n = max(3, int(round(window_s * sample_rate_hz)))
    if len(gyro) < n:
        raise AnalysisError(f"stationarity: {len(gyro)} samples, fewer than one window ({window_s:g} s)")
    given = gyro_sigma is not None and accel_sigma is not None
    sg = np.broadcast_to(np.asarray(gyro_sigma, float), 3) if gyro_sigma is not None else estimate_sigma(gyro, n)
    sa = np.broadcast_to(np.asarray(accel_sigma, float), 3) if accel_sigma is not None else estimate_sigma(accel, n)
    vg, mg = _window_sums(gyro, n)
    va, _ = _window_sums(accel, n)
    var_stat = (vg / sg**2).sum(axis=1) + (va / sa**2).sum(axis=1)
    dof1 = 6 * (n - 1)
    thr1 = float(_chi2_ppf(1 - false_alarm, dof1))
    min_len = max(1, int(round(min_still_s * sample_rate_hz)))
    first = _centred(var_stat, len(gyro), n) <= thr1
    stretches = _runs(first, min_len)
    if stretches and not given:  # refine the noise on the still windows themselves (any noise colour)
        w = np.clip(np.concatenate([np.arange(a, b) for a, b in stretches]) - n // 2, 0, len(vg) - 1)
        if gyro_sigma is None:
            sg = np.maximum(np.sqrt(vg[w].mean(axis=0) / (n - 1)), _floor(gyro))
        if accel_sigma is None:
            sa = np.maximum(np.sqrt(va[w].mean(axis=0) / (n - 1)), _floor(accel))
        var_stat = (vg / sg**2).sum(axis=1) + (va / sa**2).sum(axis=1)
        stretches = _runs(_centred(var_stat, len(gyro), n) <= thr1, min_len)
    if not stretches:
        return Stillness(np.zeros(len(gyro), bool), [], _centred(var_stat, len(gyro), n) / dof1, thr1 / dof1, n,
                         sg.copy(), sa.copy(), "given" if given else "estimated", np.full(3, np.nan), false_alarm)
    sel = np.concatenate([np.arange(a, b) for a, b in stretches])
    bias = np.median(gyro[sel], axis=0)  # a steady turn passes the variance test: the median ignores it
    gmean = mg + gyro.mean(axis=0)  # window means (the running sums were of centred values)
    dof = dof1 + 3
    thr = float(_chi2_ppf(1 - false_alarm, dof))
    for _ in range(2):  # the bias of the still stretches, then the stretches with that bias
        excess = np.maximum(np.linalg.norm((gmean - bias) / sg, axis=1) - (EARTH_RATE + rate_tolerance) / sg.min(), 0.0)
        per_sample = _centred(var_stat + n * excess**2, len(gyro), n)
        stretches = _runs(per_sample <= thr, min_len)
        if not stretches:
            break
        bias = gyro[np.concatenate([np.arange(a, b) for a, b in stretches])].mean(axis=0)
    still = np.zeros(len(gyro), bool)
    for a, b in stretches:
        still[a:b] = True
    return Stillness(still, stretches, per_sample / dof, thr / dof, n, sg.copy(), sa.copy(),
                     "given" if given else "estimated", bias, false_alarm)


def moving_summary(st: Stillness, t: np.ndarray, gyro: np.ndarray) -> str:
    """One phrase on the motion a record shows: moving fraction, longest moving stretch, peak rate (°/s)."""
    moving = ~st.still
    runs = _runs(moving, 1)
    longest = max((t[b - 1] - t[a] for a, b in runs), default=0.0)
    bias = np.nan_to_num(st.gyro_bias)
    peak = float(np.degrees(np.linalg.norm(gyro - bias, axis=1)[moving].max())) if moving.any() else 0.0
    return (f"moving {moving.mean():.0%} of the time (longest {longest:.1f} s, up to {peak:.3g} °/s), "
            f"{len(st.stretches)} still stretch(es)")
