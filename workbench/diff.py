"""Differences between two calibration sets, coefficient by coefficient, in units of sigma.

A change is measured in sigma only where *both* versions observed the coefficient (finite
sigma on both sides). A coefficient one version did not observe (sigma null: its value is the
prior, zero) is its own state, "not observed in A" / "not observed in B", never a change in
sigma: comparing an estimate with a prior says nothing about the unit.

Values are SI in both sets (the calibration format's one unit per coefficient); the CLI and the
dashboard show them in the lab unit of :mod:`workbench.units`, labelled. Sets of two different
models, or with no triad in common, are refused (their coefficients are not the same quantities);
thermal polynomials about different reference temperatures, or of different orders, are
:data:`NOT_COMPARABLE` (the set holds no covariance to carry sigmas to a common reference).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.calset import TRIADS, CalibrationSet
from workbench.errors import CalibrationFormatError
from workbench.model import COEFFICIENT_FIELDS


CHANGED = "changed"  # both observed: change_in_sigma is finite
NOT_OBSERVED_A = "not observed in A"  # the old version did not observe it (sigma null)
NOT_OBSERVED_B = "not observed in B"  # the new version did not observe it
NOT_OBSERVED = "not observed in A or B"
ONLY_A = "only in A"  # a triad / field one set does not have at all
ONLY_B = "only in B"
NOT_COMPARABLE = "not comparable"  # thermal polynomials about different t_ref or of different orders: ``note`` says


@dataclass(frozen=True)
class DiffRow:
    """One coefficient that differs between set A (old) and B (new), SI values.

    ``state`` is one of :data:`CHANGED`, :data:`NOT_OBSERVED_A`, :data:`NOT_OBSERVED_B`,
    :data:`NOT_OBSERVED`, :data:`ONLY_A`, :data:`ONLY_B`. ``change_in_sigma`` =
    (new - old) / sqrt(s_old^2 + s_new^2) only in state ``changed`` (NaN otherwise), ``sigma``
    that combined sigma (NaN otherwise). ``index`` is the element index within the field,
    e.g. ``(0, 1)`` for M[0, 1]. ``note`` says why a row is :data:`NOT_COMPARABLE`.
    """

    triad: str
    field: str
    index: tuple[int, ...]
    old: float
    new: float
    sigma: float
    change_in_sigma: float
    state: str = CHANGED
    note: str = ""

    @property
    def observed_in_both(self) -> bool:
        """True when both versions observed the coefficient (the change in sigma is meaningful)."""
        return self.state == CHANGED


def _field_pairs(a: CalibrationSet, b: CalibrationSet):
    for triad in TRIADS:
        ta, tb = a.triads.get(triad), b.triads.get(triad)
        if ta is None or tb is None:
            continue
        for f in COEFFICIENT_FIELDS:
            va, vb = getattr(ta.model, f), getattr(tb.model, f)
            if va is not None and vb is not None:
                yield triad, f, va, vb, ta.sigma_of(f), tb.sigma_of(f)
        tha, thb = ta.model.thermal, tb.model.thermal
        if tha is not None and thb is not None:
            for f in ("bias_poly", "scale_poly"):
                va, vb = getattr(tha, f), getattr(thb, f)
                if va.size and vb.size and _thermal_mismatch(tha, thb, f) is None:
                    yield triad, f"thermal.{f}", va, vb, ta.sigma_of(f"thermal.{f}"), tb.sigma_of(f"thermal.{f}")


def _thermal_mismatch(tha, thb, f: str) -> str | None:
    """Why the thermal polynomials ``f`` of two sets cannot be compared element by element (None if they can)."""
    if tha.t_ref_c != thb.t_ref_c:
        return f"about different reference temperatures (A {tha.t_ref_c:g} °C, B {thb.t_ref_c:g} °C)"
    ka, kb = getattr(tha, f).shape[1], getattr(thb, f).shape[1]
    return None if ka == kb else f"of different orders (A {ka - 1}, B {kb - 1})"


def _comparable(a: CalibrationSet, b: CalibrationSet) -> None:
    """CalibrationFormatError when ``a`` and ``b`` hold different quantities: other models, no common triad."""
    if a.unit.model and b.unit.model and a.unit.model != b.unit.model:
        raise CalibrationFormatError(f"sets diff: A {a.id[:8]} is a {a.unit.model!r} ({a.unit.serial}), B {b.id[:8]} "
                                     f"a {b.unit.model!r} ({b.unit.serial}): different models are not compared "
                                     "coefficient by coefficient")
    if a.triads and b.triads and not set(a.triads) & set(b.triads):
        raise CalibrationFormatError(f"sets diff: A {a.id[:8]} holds {', '.join(a.triads)}, B {b.id[:8]} holds "
                                     f"{', '.join(b.triads)}: no sensor in common to compare")


def _state(sa: float, sb: float) -> str:
    if np.isfinite(sa) and np.isfinite(sb):
        return CHANGED
    if np.isfinite(sb):
        return NOT_OBSERVED_A
    return NOT_OBSERVED_B if np.isfinite(sa) else NOT_OBSERVED


def diff_sets(a: CalibrationSet, b: CalibrationSet, rtol: float = 0.0) -> list[DiffRow]:
    """Coefficients that differ between set ``a`` (old) and ``b`` (new).

    Changes observed in both versions come first, largest |change in sigma| first; then the
    coefficients not observed in one or both versions, thermal polynomials that cannot be compared,
    then triads present in only one set. CalibrationFormatError for sets of different models or
    without a triad in common (module docstring).
    """
    _comparable(a, b)
    rows: list[DiffRow] = []
    for triad, f, va, vb, sa, sb in _field_pairs(a, b):
        for idx in zip(*np.nonzero(~np.isclose(va, vb, rtol=rtol, atol=0.0))):
            state = _state(float(sa[idx]), float(sb[idx]))
            s = float(np.hypot(sa[idx], sb[idx])) if state == CHANGED else np.nan
            change = (vb[idx] - va[idx]) / s if state == CHANGED and s > 0 else np.nan
            rows.append(DiffRow(triad, f, tuple(int(i) for i in idx), float(va[idx]), float(vb[idx]), s,
                                float(change), state))
    for triad in TRIADS:
        tha, thb = (getattr(getattr(s.triads.get(triad), "model", None), "thermal", None) for s in (a, b))
        for f in ("bias_poly", "scale_poly") if tha is not None and thb is not None else ():
            why = _thermal_mismatch(tha, thb, f) if getattr(tha, f).size and getattr(thb, f).size else None
            if why is not None:
                rows.append(DiffRow(triad, f"thermal.{f}", (), np.nan, np.nan, np.nan, np.nan, NOT_COMPARABLE, why))
        if (triad in a.triads) != (triad in b.triads):
            rows.append(DiffRow(triad, "(triad)", (), np.nan, np.nan, np.nan, np.nan,
                                ONLY_A if triad in a.triads else ONLY_B))
    order = {CHANGED: 0, NOT_OBSERVED_A: 1, NOT_OBSERVED_B: 1, NOT_OBSERVED: 2, NOT_COMPARABLE: 3, ONLY_A: 4, ONLY_B: 4}
    return sorted(rows, key=lambda r: (order[r.state],
                                       -abs(r.change_in_sigma) if np.isfinite(r.change_in_sigma) else 0.0))
