"""Earth model: WGS-84 constants, normal gravity, Earth rate, local frames.

Navigation frame is NED (north, east, down); body frame is x forward, y right, z down.

Public: ``WGS84_A``, ``WGS84_F``, ``WGS84_E2``, ``EARTH_RATE``, ``GM``,
:func:`normal_gravity`, :func:`gravity_ned`, :func:`earth_rate_ned`,
:func:`horizontal_earth_rate`, :func:`radii`, :func:`rz`.

References: NIMA TR8350.2 (WGS-84) eq. 4-1 (Somigliana) and 4-3 (height correction);
thesis (shared/seeds/000_...) sec. 3.3 for the NED mechanisation quantities.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

WGS84_A = 6378137.0  # m, semi-major axis
WGS84_F = 1.0 / 298.257223563  # flattening
WGS84_B = WGS84_A * (1.0 - WGS84_F)  # m, semi-minor axis
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)  # first eccentricity squared
EARTH_RATE = 7.292115e-5  # rad/s, WGS-84 angular velocity
GM = 3.986004418e14  # m^3/s^2
GAMMA_E = 9.7803253359  # m/s^2, normal gravity at the equator
GAMMA_P = 9.8321849378  # m/s^2, normal gravity at the poles
_K_SOMIGLIANA = (WGS84_B * GAMMA_P) / (WGS84_A * GAMMA_E) - 1.0
_M = EARTH_RATE**2 * WGS84_A**2 * WGS84_B / GM


def normal_gravity(latitude: float | np.ndarray, height: float | np.ndarray = 0.0) -> np.ndarray:
    """Magnitude of normal gravity (m/s^2) at geodetic ``latitude`` (rad) and ``height`` (m).

    Somigliana's closed formula on the ellipsoid, with the second-order free-air
    correction for height above it.
    """
    s2 = np.sin(latitude) ** 2
    g0 = GAMMA_E * (1.0 + _K_SOMIGLIANA * s2) / np.sqrt(1.0 - WGS84_E2 * s2)
    h = np.asarray(height, dtype=float)
    corr = 1.0 - 2.0 / WGS84_A * (1.0 + WGS84_F + _M - 2.0 * WGS84_F * s2) * h + 3.0 / WGS84_A**2 * h**2
    return g0 * corr


def gravity_ned(latitude: float, height: float = 0.0) -> np.ndarray:
    """Normal gravity vector (3,) in NED, m/s^2 (pointing down)."""
    return np.array([0.0, 0.0, float(normal_gravity(latitude, height))])


def earth_rate_ned(latitude: float) -> np.ndarray:
    """Earth rotation rate vector (3,) in NED at geodetic ``latitude`` (rad), rad/s."""
    return EARTH_RATE * np.array([np.cos(latitude), 0.0, -np.sin(latitude)])


def horizontal_earth_rate(latitude: float) -> float:
    """Horizontal (north) component of the Earth rate, ``Omega_e cos(latitude)``, rad/s."""
    return float(EARTH_RATE * np.cos(latitude))


def radii(latitude: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Meridian and normal (prime-vertical) radii of curvature ``(R_M, R_N)``, m, at geodetic ``latitude`` rad."""
    s2 = np.sin(latitude) ** 2
    rn = WGS84_A / np.sqrt(1.0 - WGS84_E2 * s2)
    return rn * (1.0 - WGS84_E2) / (1.0 - WGS84_E2 * s2), rn


def rz(angle: float | np.ndarray) -> Rotation:
    """Rotation about the down (z) axis by ``angle`` rad, positive clockwise seen from above.

    Applied to a vector expressed in the rotated frame it gives the vector in the
    fixed frame (e.g. table-top frame to NED when ``angle`` is the table azimuth).
    """
    angle = np.asarray(angle, float)
    return Rotation.from_euler("z", angle[:, None] if angle.ndim == 1 else angle)
