"""Magnetometer fits that use what the lab knows: the gravity direction and the table attitude.

- :func:`fit_dip`: the accelerometer gives the down direction ``d`` in the IMU axes; the
  field makes a constant angle with it (dip ``δ``), so besides ``|h| = F`` every point obeys
  ``d · h = F sin δ``; each constraint is weighted by its own robust scatter (the dip's carries
  the accelerometer's noise and, by hand, the motion's accelerations). With ``h = inv(G) (m - b)`` and ``G = F (I + M)`` a full (non-symmetric)
  ``G`` is fitted (both constraints as first-order distances of ``m`` in µT): the second equation fixes the rotation an ellipsoid leaves free, i.e. the
  rotation between magnetometer and accelerometer axes, and it holds the fit together when
  the sphere is covered only in a cap (limited tilt).
- :func:`fit_attitude`: with the body-to-reference attitude ``C_k`` known from the table
  angles (vector least squares), ``m_k = G C_k^T h_ref + b`` with
  ``h_ref = [cos δ cos D, cos δ sin D, sin δ]``: every component of every sample is used,
  ``G`` is fully observed (including the magnetometer-to-IMU rotation, the polar factor
  ``U`` of ``I + M = P U``) together with dip and declination ``D`` (from the reference x axis,
  true north when the table zero azimuth is known). The initial value comes from a linear
  least-squares fit of ``W = G ⊗ h_ref`` (27 coefficients) and its rank-1 factorisation.

Both report ``I + M`` and ``F`` under the scale convention of :func:`workbench.analysis.mag_fit.gain_to_model`.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from workbench.analysis.mag_ellipsoid import fit_ellipsoid, fit_sphere
from workbench.analysis.mag_fit import MagFit, build_fit, solve
from workbench.angles import wrap_pi as _wrap
from workbench.errors import AnalysisError


def down_direction(accel: np.ndarray) -> np.ndarray:
    """Unit down vector (N, 3) in the IMU body frame from static specific force (N, 3) m/s^2 (``d = -f/|f|``)."""
    return -accel / np.linalg.norm(accel, axis=1, keepdims=True)


def fit_dip(mag: np.ndarray, accel: np.ndarray, field_norm_ut: float | None = None, robust: bool | str = False,
            warnings: tuple[str, ...] = (), gravity_ok: np.ndarray | None = None) -> MagFit:
    """Hard iron, full soft iron (incl. rotation to the accelerometer axes), field norm and dip.

    Parameters
    ----------
    mag : (N, 3) µT raw magnetometer samples
    accel : (N, 3) m/s^2 specific force in the IMU body frame at the same instants (static or slow motion)
    field_norm_ut : reference field magnitude µT, or None (det(I + M) = 1)
    robust : reject outliers before the final fit
    gravity_ok : (N,) bool, the points whose specific force is gravity (quasi-static); only they carry the
        dip constraint, every point the norm constraint (default: all)
    """
    d = down_direction(accel)
    w_dip = np.ones(len(mag)) if gravity_ok is None else np.asarray(gravity_ok, float)
    starts = []
    for init in (fit_ellipsoid, fit_sphere):
        try:
            f0 = init(mag, robust=robust)
        except AnalysisError:
            continue
        g0 = f0.field_norm_ut * f0.soft_iron
        h = (mag - f0.bias) @ np.linalg.inv(g0).T
        dip0 = float(np.median(np.arcsin(np.clip(np.sum(d * h, axis=1) / np.linalg.norm(h, axis=1), -1, 1))[w_dip > 0]))
        starts.append(np.concatenate([f0.bias, np.linalg.inv(g0).ravel(), [dip0]]))
    if not starts:
        raise AnalysisError("dip fit: no starting ellipsoid or sphere could be fitted")

    best = None
    weight = np.ones(2)  # of the norm and the dip residuals: each group by its own scatter (set below)

    def resid(p, idx):
        b = p[3:12].reshape(3, 3)
        u = (mag[idx] - p[:3]) @ b.T  # unit-field vector in the IMU axes
        nu = np.linalg.norm(u, axis=1)
        # both constraints as first-order distances of m (µT): residual / |gradient wrt m|
        norm_res = (nu - 1.0) * nu / np.linalg.norm(u @ b, axis=1)
        dip_res = w_dip[idx] * (np.sum(d[idx] * u, axis=1) - np.sin(p[12])) / np.linalg.norm(d[idx] @ b, axis=1)
        return np.column_stack([norm_res, dip_res]) * weight

    for p0 in starts:
        sol = solve(resid, p0, len(mag), robust)
        cost = float(np.mean(sol.residuals**2))
        if best is None or cost < best[0]:
            best = (cost, sol)
    # the two constraints have their own noise (the dip's includes the accelerometer's and, by hand, motion):
    # weight each by its robust scatter (MAD) at the solution, in units of the norm residual, and refit
    r = best[1].residuals
    spread = 1.4826 * np.median(np.abs(r[:, 1][w_dip[best[1].inliers] > 0])) if (w_dip > 0).any() else 0.0
    if spread > 0:
        weight[1] = min(1.0, 1.4826 * float(np.median(np.abs(r[:, 0]))) / spread)
        sol = solve(resid, best[1].p, len(mag), robust)
    else:
        sol = best[1]
    notes = list(warnings)
    if robust and (~sol.inliers).any():
        notes.append(f"robust fit: {int((~sol.inliers).sum())} of {len(mag)} points rejected as outliers")
    return build_fit("dip", sol, lambda p: (p[:3], np.linalg.inv(p[3:12].reshape(3, 3))), field_norm_ut,
                     observes_rotation=True, warnings=notes, angles=lambda p: np.array([p[12], np.nan]))


def _field_ref(dip: float, decl: float) -> np.ndarray:
    """Unit field vector in the reference frame (x north/table zero, y east, z down)."""
    return np.array([np.cos(dip) * np.cos(decl), np.cos(dip) * np.sin(decl), np.sin(dip)])


def _linear_start(mag: np.ndarray, ct: np.ndarray) -> np.ndarray:
    """Initial parameters from the linear model ``m = W vec(C^T) + b`` and the rank-1 split ``W = G ⊗ h_ref``."""
    design = np.column_stack([ct.reshape(len(ct), 9), np.ones(len(ct))])
    coef = np.linalg.lstsq(design, mag, rcond=None)[0]  # (10, 3)
    w = coef[:9].T.reshape(3, 3, 3)  # [r, i, j] = G[r, i] h[j]
    u, s, vt = np.linalg.svd(w.reshape(9, 3))
    g, h = s[0] * u[:, 0].reshape(3, 3), vt[0]
    if np.linalg.det(g) < 0:
        g, h = -g, -h
    return np.concatenate([g.ravel(), coef[9], [np.arcsin(np.clip(h[2], -1, 1)), np.arctan2(h[1], h[0])]])


def fit_attitude(mag: np.ndarray, attitude: Rotation, field_norm_ut: float | None = None, robust: bool | str = False,
                 warnings: tuple[str, ...] = ()) -> MagFit:
    """Vector least squares with known attitude: full ``I + M``, hard iron, field norm, dip, declination.

    Parameters
    ----------
    mag : (N, 3) µT raw magnetometer samples
    attitude : N body(IMU)-to-reference rotations (reference = NED, or the level table-zero frame)
    field_norm_ut : reference field magnitude µT, or None (det(I + M) = 1)
    robust : reject outliers before the final fit
    """
    ct = attitude.inv().as_matrix()  # (N, 3, 3) reference -> body
    p0 = _linear_start(mag, ct)

    def resid(p, idx):
        u = ct[idx] @ _field_ref(p[12], p[13])
        return mag[idx] - u @ p[:9].reshape(3, 3).T - p[9:12]

    sol = solve(resid, p0, len(mag), robust)
    notes = list(warnings)
    if robust and (~sol.inliers).any():
        notes.append(f"robust fit: {int((~sol.inliers).sum())} of {len(mag)} points rejected as outliers")
    return build_fit("attitude", sol, lambda p: (p[9:12], p[:9].reshape(3, 3)), field_norm_ut,
                     observes_rotation=True, warnings=notes, angles=lambda p: np.array([p[12], _wrap(p[13])]))
