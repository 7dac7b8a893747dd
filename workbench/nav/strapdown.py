"""Strapdown building blocks shared by the AHRS and the ZUPT alignment.

Attitude propagation over a block of gyro samples (vectorised with scipy Rotation), coarse
levelling from the accelerometers, Euler angles and attitude-error metrics.

Attitude is the body-to-NED rotation ``C_b^n`` as a :class:`scipy.spatial.transform.Rotation`.
Its kinematics with the Earth rate removed (thesis eq. 3.6, ``q_dot = q * (w_ib - C_n^b w_ie) / 2``)
has the exact solution ``C(t) = Exp(-w_ie t) C(0) prod_k Exp(w_k dt)``: the Earth term is a
rotation of the navigation frame, the gyro term a product of body increments, so a block is
propagated with one prefix product (log2 n vectorised compositions) instead of a Python loop.

Public: :func:`propagate_block`, :func:`coarse_level`, :func:`euler_rph`, :func:`attitude_errors`,
:func:`rotation_error_ned`.

References: thesis (shared/seeds/000_...) eq. 3.6, 3.38-3.45, 3.54-3.56.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def _prefix_product(r: Rotation) -> Rotation:
    """Cumulative products ``r[0], r[0]*r[1], ..., r[0]*...*r[n-1]`` (Hillis-Steele scan)."""
    n = len(r)
    s = 1
    while s < n:
        r = Rotation.concatenate([r[:s], r[:-s] * r[s:]])
        s *= 2
    return r


def propagate_block(c0: Rotation, omega_b: np.ndarray, dt: float, earth_rate_ned: np.ndarray) -> Rotation:
    """Body-to-NED attitudes after each of the ``n`` gyro samples of a block.

    ``c0`` attitude at the block start; ``omega_b`` (n, 3) rad/s body rates w.r.t. inertial
    space, already bias-corrected; ``earth_rate_ned`` (3,) rad/s. Returns ``n`` rotations, the
    last one the attitude at the block end. Each sample is a constant rate over ``dt``.
    """
    n = len(omega_b)
    inc = _prefix_product(Rotation.from_rotvec(np.asarray(omega_b) * dt))
    earth = Rotation.from_rotvec(-np.outer(np.arange(1, n + 1) * dt, earth_rate_ned))
    return earth * (c0 * inc)


def coarse_level(accel: np.ndarray) -> tuple[float, float]:
    """Roll and pitch (rad) from the mean specific force (n, 3) m/s^2 of a static unit, body frame.

    ``f_b = C_n^b (0, 0, -g)``: roll = atan2(-f_y, -f_z), pitch = atan2(f_x, sqrt(f_y^2 + f_z^2)).
    """
    f = np.mean(np.atleast_2d(accel), axis=0)
    return float(np.arctan2(-f[1], -f[2])), float(np.arctan2(f[0], np.hypot(f[1], f[2])))


def from_rph(roll: float, pitch: float, heading: float) -> Rotation:
    """Body-to-NED attitude from roll, pitch, heading (rad; thesis eq. 3.38-3.41, ZYX order)."""
    return Rotation.from_euler("ZYX", [heading, pitch, roll])


def euler_rph(att: Rotation) -> np.ndarray:
    """Roll, pitch, heading (…, 3) rad of body-to-NED attitudes (thesis eq. 3.54-3.56)."""
    import warnings

    with warnings.catch_warnings():  # gimbal lock at pitch ±90° is reported, not fatal
        warnings.simplefilter("ignore", UserWarning)
        zyx = att.as_euler("ZYX")
    return zyx[..., ::-1]


def _wrap(a: np.ndarray) -> np.ndarray:
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def attitude_errors(estimate: Rotation, truth: Rotation) -> np.ndarray:
    """Estimated minus true roll, pitch, heading (…, 3) rad, wrapped to (-pi, pi].

    Roll and heading are NaN where the true pitch is within 5° of ±90° (Euler angles undefined).
    """
    err = _wrap(euler_rph(estimate) - euler_rph(truth))
    pitch = euler_rph(truth)[..., 1]
    lock = np.abs(pitch) > np.radians(85.0)
    err = np.array(err, float)
    err[..., 0] = np.where(lock, np.nan, err[..., 0])
    err[..., 2] = np.where(lock, np.nan, err[..., 2])
    return err


def rotation_error_ned(estimate: Rotation, truth: Rotation) -> np.ndarray:
    """Small-angle attitude error (…, 3) rad, NED: ``Exp(e) = truth * estimate^-1`` (defined at any attitude)."""
    return (truth * estimate.inv()).as_rotvec()
