"""Reference geomagnetic field at the site from the IGRF model (``ppigrf``), to check a fit.

The International Geomagnetic Reference Field (IGRF-14, through the pure-Python ``ppigrf``
package) gives the main field at a place and date; local anomalies and the lab building can
differ by a few µT and degrees, so the comparison raises warnings, never errors, and the
reference never replaces the fit.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime

import numpy as np


@dataclass(frozen=True)
class ReferenceField:
    """Main-field magnitude (µT), dip (rad, down positive) and declination (rad, east positive)."""

    norm_ut: float
    dip: float
    declination: float
    source: str = "IGRF"

    def to_dict(self) -> dict:
        return {"source": self.source, "norm_ut": self.norm_ut, "dip_deg": float(np.degrees(self.dip)),
                "declination_deg": float(np.degrees(self.declination))}


def igrf_field(latitude_deg: float, longitude_deg: float, height_m: float, date: datetime) -> ReferenceField:
    """IGRF main field at a geodetic position (degrees, metres above the ellipsoid) and date."""
    import ppigrf

    be, bn, bu = (float(np.ravel(c)[0]) for c in ppigrf.igrf(longitude_deg, latitude_deg, height_m / 1000.0, date))
    h = np.hypot(bn, be)
    return ReferenceField(float(np.sqrt(h**2 + bu**2)) / 1000.0, float(np.arctan2(-bu, h)), float(np.arctan2(be, bn)))


def compare(fit, ref: ReferenceField, norm_tol: float = 0.05, angle_tol_deg: float = 2.0) -> list[str]:
    """Warnings where a fit's field norm (when estimated) or dip differs from the reference."""
    notes = []
    if fit.scale_fixed_by == "det" and abs(fit.field_norm_ut / ref.norm_ut - 1.0) > norm_tol:
        notes.append(f"fitted field norm {fit.field_norm_ut:.4g} µT differs from the {ref.source} "
                     f"{ref.norm_ut:.4g} µT by more than {norm_tol:.0%} (local anomaly or scale error)")
    if fit.dip is not None and abs(np.degrees(fit.dip - ref.dip)) > angle_tol_deg:
        notes.append(f"fitted dip {np.degrees(fit.dip):.2f}° differs from the {ref.source} "
                     f"{np.degrees(ref.dip):.2f}° by more than {angle_tol_deg:g}°")
    return notes
