"""Merging partial calibration sets of one unit into one (what a campaign and ``workbench sets merge`` do).

:func:`merge`: element by element, a coefficient comes from the set that determines it best
(the smallest finite 1-sigma; among equals, or where no set observed it, the latest); a thermal
block, a field norm and noise terms from the latest set that reports them; provenance is the
union. Sigmas are 1-sigma SI, NaN = not observed (:mod:`workbench.calset`).
"""

from __future__ import annotations

import numpy as np

from workbench.calset import CalibrationSet, Provenance, TriadCalibration
from workbench.errors import CalibrationFormatError
from workbench.model import COEFFICIENT_FIELDS, TriadModel
from workbench.values import Unit


def _merge_array(old: np.ndarray, old_sig: np.ndarray, new: np.ndarray, new_sig: np.ndarray):
    """Element-wise: the better-determined estimate (smaller finite sigma; the newer on a tie or
    when neither is observed)."""
    if old.shape != new.shape:
        return new, new_sig
    take_new = ~np.isfinite(old_sig) | (np.isfinite(new_sig) & (new_sig <= old_sig))
    return np.where(take_new, new, old), np.where(take_new, new_sig, old_sig)


def _merge_triads(old: TriadCalibration, new: TriadCalibration) -> TriadCalibration:
    fields, sigma = {}, dict(old.sigma)
    for f in COEFFICIENT_FIELDS:
        o, n = getattr(old.model, f), getattr(new.model, f)
        if n is None or o is None:
            fields[f] = n if n is not None else o
            if n is not None and f in new.sigma:
                sigma[f] = new.sigma[f]
            continue
        fields[f], sigma[f] = _merge_array(o, old.sigma_of(f), n, new.sigma_of(f))
    thermal, trange = old.model.thermal, old.thermal_range_c
    if new.model.thermal is not None:
        thermal, trange = new.model.thermal, new.thermal_range_c
        for key in ("thermal.bias_poly", "thermal.scale_poly"):
            sigma.pop(key, None)
            if key in new.sigma:
                sigma[key] = new.sigma[key]
    norm, norm_sigma = old.field_norm_ut, old.field_norm_ut_sigma
    if new.field_norm_ut is not None:
        norm, norm_sigma = new.field_norm_ut, new.field_norm_ut_sigma
    return TriadCalibration(TriadModel(**fields, thermal=thermal), sigma, norm, norm_sigma, trange)


def merge(*sets: CalibrationSet) -> CalibrationSet:
    """Merge partial sets of one unit into one.

    Element by element, a coefficient comes from the set that determines it best (the
    smallest finite 1-sigma; among equals, or where no set observed it, the latest); a thermal
    block and noise terms from the latest set that reports them; provenance is the union.
    """
    if not sets:
        raise CalibrationFormatError("merge: no calibration sets given")
    serials = {s.unit.serial for s in sets}
    if len(serials) > 1:
        raise CalibrationFormatError(f"merge: sets belong to different units ({', '.join(sorted(serials))})")
    triads: dict[str, TriadCalibration] = {}
    noise: dict[str, dict] = {}
    notes: dict = {}
    for s in sets:
        for name, tc in s.triads.items():
            triads[name] = _merge_triads(triads[name], tc) if name in triads else tc
        for name, terms in s.noise.items():
            block = noise.setdefault(name, {})
            for term, values in terms.items():
                if term.endswith("_ci95"):
                    continue
                if values is not None and any(v is not None for v in values) or term not in block:
                    block[term] = values
                    if term + "_ci95" in terms:
                        block[term + "_ci95"] = terms[term + "_ci95"]
        notes.update(s.notes)
    prov = Provenance(
        procedures=tuple(dict.fromkeys(p for s in sets for p in s.provenance.procedures)),
        sessions=tuple(x for s in sets for x in s.provenance.sessions),
        merged_from=tuple(s.id for s in sets),
    )
    model = next((s.unit.model for s in reversed(sets) if s.unit.model), "")
    return CalibrationSet(unit=Unit(sets[0].unit.serial, model), triads=triads, noise=noise,
                          provenance=prov, notes=notes)
