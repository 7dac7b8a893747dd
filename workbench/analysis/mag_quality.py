"""Coverage and quality of a magnetometer calibration.

- :func:`sphere_coverage`: fraction of an equal-area grid on the unit sphere visited by the
  field directions. The grid has ``n_bands`` bands of equal height in ``z`` (Archimedes: equal
  height = equal area) each cut into ``n_lon`` equal longitude cells, so every cell has area
  ``4 pi / (n_bands n_lon)``; the default 12 x 24 cells are ~12° across.
- :func:`thickness`: smallest principal standard deviation (µT) of the raw point cloud; about
  the noise when all points lie in one plane (a level yaw sweep), where a 3D fit is not
  observable (a ±15° fixture gives ~4 µT, a level one 0.3 µT at 0.3 µT noise).
- :func:`assess`: the :class:`Quality` record of a fit (coverage, thickness, field-norm
  residual, spread of the gravity directions, the fitted norm against the 15-80 µT range and
  an optional reference) and its warnings.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.analysis.mag_fit import FIELD_RANGE_UT, MagFit
from workbench.json_values import json_value

COVERAGE_FOR_ELLIPSOID = 0.5  # fraction of the sphere an unaided 9-parameter ellipsoid needs
FLAT_LIMIT_UT = 2.0  # µT, thickness below which the cloud counts as planar (±5° of tilt gives ~1.4 µT)
NORM_TOLERANCE = 0.05  # relative difference to a reference field norm that triggers a warning


def sphere_coverage(directions: np.ndarray, n_bands: int = 12, n_lon: int = 24) -> float:
    """Fraction (0-1) of equal-area sphere cells holding at least one of the unit ``directions`` (N, 3)."""
    u = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    band = np.clip(((u[:, 2] + 1.0) / 2.0 * n_bands).astype(int), 0, n_bands - 1)
    lon = np.clip(((np.arctan2(u[:, 1], u[:, 0]) + np.pi) / (2 * np.pi) * n_lon).astype(int), 0, n_lon - 1)
    return len(set(zip(band.tolist(), lon.tolist()))) / (n_bands * n_lon)


def thickness(points: np.ndarray) -> float:
    """Smallest principal standard deviation (µT) of a point cloud (N, 3) µT; ~noise when coplanar."""
    sv = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    return float(sv[-1] / np.sqrt(len(points)))


def gravity_spread(down: np.ndarray) -> float:
    """Largest angle (rad) between a down direction (N, 3) and their mean: 0 for a single tilt."""
    u = down / np.linalg.norm(down, axis=1, keepdims=True)
    mean = u.mean(axis=0)
    mean /= np.linalg.norm(mean)
    return float(np.arccos(np.clip(u @ mean, -1, 1)).max())


@dataclass(frozen=True)
class Quality:
    """Quality figures of a calibration (µT, rad, fractions) and the warnings they raise."""

    coverage: float
    thickness_ut: float
    gravity_spread: float | None
    norm_residual_rms_ut: float
    norm_residual_max_ut: float
    reference_norm_ut: float | None
    warnings: tuple[str, ...]

    def to_dict(self) -> dict:
        """JSON-ready (µT, gravity spread in °; a figure not observed, e.g. the norm residual of a 2D fit, None)."""
        return {"coverage": self.coverage, "thickness_ut": self.thickness_ut,
                "gravity_spread_deg": None if self.gravity_spread is None else json_value(np.degrees(self.gravity_spread)),
                "norm_residual_rms_ut": json_value(self.norm_residual_rms_ut),
                "norm_residual_max_ut": json_value(self.norm_residual_max_ut),
                "reference_norm_ut": self.reference_norm_ut, "warnings": list(self.warnings)}


def assess(fit: MagFit, mag: np.ndarray, down: np.ndarray | None = None,
           reference_norm_ut: float | None = None) -> Quality:
    """Quality of ``fit`` on raw samples ``mag`` (N, 3) µT; ``down`` (N, 3) unit down directions if known."""
    h = fit.compensate(mag)
    cov = sphere_coverage(h)
    flat = thickness(mag)
    spread = gravity_spread(down) if down is not None else None
    norm_res = np.linalg.norm(h, axis=1) - fit.field_norm_ut
    notes = []
    planar = fit.method.startswith("2d")
    if fit.method in ("ellipsoid", "algebraic") and cov < COVERAGE_FOR_ELLIPSOID:
        notes.append(f"coverage {cov:.0%} of the sphere cannot support an unaided ellipsoid "
                     f"(needs >= {COVERAGE_FOR_ELLIPSOID:.0%}): soft iron and hard iron along the unseen "
                     "directions are poorly determined; use table angles or tilts")
    if planar and flat >= FLAT_LIMIT_UT:
        notes.append(f"2D method on data that are not level (cloud {flat:.3g} µT thick >= {FLAT_LIMIT_UT} µT): "
                     "the 2D model does not hold; heading errors will be large")
    if not planar:
        lo, hi = FIELD_RANGE_UT
        if not lo <= fit.field_norm_ut <= hi:
            notes.append(f"fitted field norm {fit.field_norm_ut:.4g} µT is outside the geomagnetic range "
                         f"{lo:g}-{hi:g} µT: strong local disturbance or wrong units")
        if reference_norm_ut is not None and fit.scale_fixed_by == "det" and \
                abs(fit.field_norm_ut / reference_norm_ut - 1) > NORM_TOLERANCE:
            notes.append(f"fitted field norm {fit.field_norm_ut:.4g} µT differs from the reference "
                         f"{reference_norm_ut:.4g} µT by more than {NORM_TOLERANCE:.0%}")
    return Quality(cov, flat, spread, float(np.sqrt(np.mean(norm_res**2))) if not planar else float("nan"),
                   float(np.abs(norm_res).max()) if not planar else float("nan"), reference_norm_ut, tuple(notes))
