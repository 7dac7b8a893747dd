"""Differences between two calibration sets, coefficient by coefficient, in units of sigma."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.calset import TRIADS, CalibrationSet

_FIELDS = ("bias", "scale_misalignment", "nonlinearity", "g_sensitivity")


@dataclass(frozen=True)
class DiffRow:
    """One coefficient that differs: ``change_in_sigma`` = (new - old) / sqrt(s_old^2 + s_new^2).

    ``change_in_sigma`` is NaN when neither set observed the coefficient's uncertainty.
    ``index`` is the element index within the field, e.g. ``(0, 1)`` for M[0, 1].
    """

    triad: str
    field: str
    index: tuple[int, ...]
    old: float
    new: float
    sigma: float
    change_in_sigma: float


def _field_pairs(a: CalibrationSet, b: CalibrationSet):
    for triad in TRIADS:
        ta, tb = a.triads.get(triad), b.triads.get(triad)
        if ta is None or tb is None:
            continue
        for f in _FIELDS:
            va, vb = getattr(ta.model, f), getattr(tb.model, f)
            if va is not None and vb is not None:
                yield triad, f, va, vb, ta.sigma_of(f), tb.sigma_of(f)
        tha, thb = ta.model.thermal, tb.model.thermal
        if tha is not None and thb is not None:
            for f in ("bias_poly", "scale_poly"):
                va, vb = getattr(tha, f), getattr(thb, f)
                if va.shape == vb.shape:
                    yield triad, f"thermal.{f}", va, vb, ta.sigma_of(f"thermal.{f}"), tb.sigma_of(f"thermal.{f}")


def diff_sets(a: CalibrationSet, b: CalibrationSet, rtol: float = 0.0) -> list[DiffRow]:
    """Coefficients that differ between set ``a`` (old) and ``b`` (new), largest change first.

    Triads present in only one set are reported as a row with NaN values for the missing side.
    """
    rows: list[DiffRow] = []
    for triad, f, va, vb, sa, sb in _field_pairs(a, b):
        sigma = np.sqrt(np.nan_to_num(sa, nan=0.0) ** 2 + np.nan_to_num(sb, nan=0.0) ** 2)
        sigma = np.where(np.isfinite(sa) | np.isfinite(sb), sigma, np.nan)
        for idx in zip(*np.nonzero(~np.isclose(va, vb, rtol=rtol, atol=0.0))):
            s = float(sigma[idx])
            change = (vb[idx] - va[idx]) / s if s > 0 else np.nan
            rows.append(DiffRow(triad, f, tuple(int(i) for i in idx), float(va[idx]), float(vb[idx]), s, float(change)))
    for triad in TRIADS:
        if (triad in a.triads) != (triad in b.triads):
            rows.append(DiffRow(triad, "(triad)", (), np.nan if triad not in a.triads else 1.0,
                                np.nan if triad not in b.triads else 1.0, np.nan, np.nan))
    return sorted(rows, key=lambda r: -abs(r.change_in_sigma) if np.isfinite(r.change_in_sigma) else 0.0)
