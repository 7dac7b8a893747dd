"""Fleet statistics: the distribution of each coefficient across the units of one grade."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.calset import CalibrationSet
from workbench.model import COEFFICIENT_FIELDS

OUTLIER_Z = 3.5  # robust z-score (median / 1.4826 MAD) above which a unit is flagged


@dataclass(frozen=True)
class CoefficientStats:
    """One coefficient across units: mean, standard deviation, median, robust spread, outliers.

    ``outliers`` lists (serial, value, robust z) of units beyond :data:`OUTLIER_Z`.
    """

    triad: str
    field: str
    index: tuple[int, ...]
    n: int
    mean: float
    std: float
    median: float
    robust_std: float
    outliers: tuple[tuple[str, float, float], ...]


def coefficient_stats(sets: list[CalibrationSet]) -> list[CoefficientStats]:
    """Statistics of every coefficient present in at least two of ``sets`` (one set per unit)."""
    values: dict[tuple, list[tuple[str, float]]] = {}
    for s in sets:
        for triad, tc in s.triads.items():
            for f in COEFFICIENT_FIELDS:
                arr = getattr(tc.model, f)
                if arr is None:
                    continue
                sig = tc.sigma_of(f)
                for idx in np.ndindex(arr.shape):
                    if np.isfinite(sig[idx]):  # only what the data observed
                        values.setdefault((triad, f, idx), []).append((s.unit.serial, float(arr[idx])))
    out = []
    for (triad, f, idx), pairs in sorted(values.items()):
        if len(pairs) < 2:
            continue
        x = np.array([v for _, v in pairs])
        med = float(np.median(x))
        rstd = float(1.4826 * np.median(np.abs(x - med)))
        z = (x - med) / rstd if rstd > 0 else np.zeros_like(x)
        outliers = tuple((serial, v, float(zz)) for (serial, v), zz in zip(pairs, z) if abs(zz) > OUTLIER_Z)
        out.append(CoefficientStats(triad, f, tuple(int(i) for i in idx), len(x), float(x.mean()),
                                    float(x.std(ddof=1)), med, rstd, outliers))
    return out
