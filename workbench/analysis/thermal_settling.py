"""Thermal settling: when the unit's own temperature stops moving.

:func:`settling` (a sliding-window slope :func:`windowed_slope`, °C/min, below a tolerance until
the end of the record) and its result :class:`Settling`. Part of the thermal analysis
(:mod:`workbench.analysis.thermal`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Settling:
    """Whether and when the unit temperature settled during one record.

    ``t_settled`` (s, session time) is the first time after which the windowed slope stays
    below the tolerance (None when it never does); ``final_rate_c_per_min`` is the slope over
    the last window, °C/min.
    """

    settled: bool
    t_settled: float | None
    final_rate_c_per_min: float
    tol_c_per_min: float


def _binned(t: np.ndarray, y: np.ndarray, bin_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Mean of ``y`` in consecutive bins of ``bin_s`` seconds (cheap decimation)."""
    idx = np.floor((t - t[0]) / bin_s).astype(int)
    counts = np.bincount(idx)
    keep = counts > 0
    tb = np.bincount(idx, t)[keep] / counts[keep]
    yb = np.bincount(idx, y)[keep] / counts[keep]
    return tb, yb


def windowed_slope(t: np.ndarray, temp_c: np.ndarray, window_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares slope of ``temp_c`` over the trailing ``window_s`` at each 1/10-window bin.

    Returns (bin times s, slope °C/s); NaN where the window is not yet full.
    """
    tb, yb = _binned(np.asarray(t, float), np.asarray(temp_c, float), window_s / 10.0)
    n = len(tb)
    slope = np.full(n, np.nan)
    if n < 3:
        return tb, slope
    x = tb - tb[0]
    c = [np.concatenate([[0.0], np.cumsum(v)]) for v in (np.ones(n), x, yb, x * x, x * yb)]
    start = np.searchsorted(tb, tb - window_s * (1 - 1e-9))
    end = np.arange(1, n + 1)
    s0, sx, sy, sxx, sxy = (ci[end] - ci[start] for ci in c)
    den = s0 * sxx - sx * sx
    full = (tb - tb[start] >= 0.8 * window_s) & (den > 0)
    slope[full] = (s0 * sxy - sx * sy)[full] / den[full]
    return tb, slope


def settling(t: np.ndarray, temp_c: np.ndarray, tol_c_per_min: float = 0.05,
             window_s: float = 120.0) -> Settling:
    """Detect settling of the unit temperature ``temp_c`` (°C) sampled at times ``t`` (s).

    The slope is fitted over a trailing window of ``window_s``; the record is settled from the
    first time after which ``|slope|`` stays below ``tol_c_per_min`` to the end.
    """
    t = np.asarray(t, float)
    if len(t) < 2 or t[-1] - t[0] < window_s:
        window_s = max((t[-1] - t[0]) if len(t) > 1 else 0.0, 1e-9)
    tb, slope = windowed_slope(t, temp_c, window_s)
    rate = np.abs(slope) * 60.0
    valid = np.isfinite(rate)
    if not valid.any():
        return Settling(False, None, float("nan"), tol_c_per_min)
    final = float(slope[valid][-1] * 60.0)
    bad = valid & (rate >= tol_c_per_min)
    if bad[valid][-1]:
        return Settling(False, None, final, tol_c_per_min)
    last_bad = np.flatnonzero(bad)
    first_ok = int(last_bad[-1] + 1) if last_bad.size else int(np.flatnonzero(valid)[0])
    return Settling(True, float(tb[first_ok]), final, tol_c_per_min)
