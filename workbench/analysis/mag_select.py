"""Automatic choice of the magnetometer estimator, with the reason (like ``magcal``'s 'auto', plus coverage).

Order of preference, each tried only when the data support it:

1. ``2d`` when the raw cloud is flat (a level yaw sweep, or less than ~5° of tilt): 3D parameters are not observable;
2. ``attitude`` when the body-to-reference attitude is known (table angles) and the gravity
   direction takes more than one value in the body (several tilts): vector least squares
   observes everything, including the magnetometer-to-IMU rotation;
3. ``dip`` when accelerometer data show several tilts: the constant-dip constraint holds the
   fit together on a partial sphere;
4. ``ellipsoid`` when the field directions cover enough of the sphere;
5. ``sphere`` (hard iron only) otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.analysis.mag_quality import COVERAGE_FOR_ELLIPSOID, FLAT_LIMIT_UT

METHODS = ("auto", "2d", "2d-minmax", "sphere", "ellipsoid", "dip", "attitude", "algebraic")
MIN_TILT_SPREAD = np.radians(5.0)  # rad, gravity-direction spread that counts as "several tilts"


@dataclass(frozen=True)
class Choice:
    """The estimator chosen and why."""

    method: str
    reason: str


def choose(thickness_ut: float, coverage: float, tilt_spread: float | None, has_attitude: bool) -> Choice:
    """Pick an estimator from the cloud's thickness (µT), its sphere ``coverage`` (0-1, of the raw
    directions about the cloud's centre), the gravity-direction spread (rad, None without
    accelerometer) and whether the attitude is known."""
    tilted = tilt_spread is not None and tilt_spread > MIN_TILT_SPREAD
    if thickness_ut < FLAT_LIMIT_UT:
        return Choice("2d", f"points lie in one plane ({thickness_ut:.3g} µT thick < {FLAT_LIMIT_UT} µT): level data, "
                            "3D hard/soft iron not observable; 2D method (paper 004)")
    if has_attitude and tilted:
        return Choice("attitude", f"table attitude known and {np.degrees(tilt_spread):.0f}° of tilt: vector "
                                  "least squares observes full soft iron, dip, declination and mag-to-IMU rotation")
    if tilted:
        return Choice("dip", f"accelerometer shows {np.degrees(tilt_spread):.0f}° of tilt: constant-dip fit "
                             f"(coverage {coverage:.0%} alone is weak for an ellipsoid)"
                      if coverage < COVERAGE_FOR_ELLIPSOID else
                      f"accelerometer shows {np.degrees(tilt_spread):.0f}° of tilt: constant-dip fit also "
                      "observes the mag-to-accelerometer rotation")
    if coverage >= COVERAGE_FOR_ELLIPSOID:
        return Choice("ellipsoid", f"coverage {coverage:.0%} >= {COVERAGE_FOR_ELLIPSOID:.0%} of the sphere: "
                                   "positive-definite ellipsoid fit")
    return Choice("sphere", f"coverage {coverage:.0%} < {COVERAGE_FOR_ELLIPSOID:.0%} and no attitude or gravity "
                            "data: hard iron and field norm only (4-parameter sphere)")
