"""Strapdown building blocks shared by the AHRS and the ZUPT alignment.

Attitude propagation over a block of gyro samples (vectorised with scipy Rotation), coarse
levelling from the accelerometers, Euler angles and attitude-error metrics.

Attitude is the body-to-NED rotation ``C_b^n``: a :class:`scipy.spatial.transform.Rotation` at the
interfaces, a (3, 3) direction-cosine matrix inside the filter loops (scipy builds every
rotation; numpy only multiplies the matrices, which is much faster than per-sample objects).
Its kinematics with the Earth rate removed (thesis eq. 3.6, ``q_dot = q * (w_ib - C_n^b w_ie) / 2``)
has the exact solution ``C(t) = Exp(-w_ie t) C(0) prod_k Exp(w_k dt)``: the Earth term is a
rotation of the navigation frame, the gyro term a product of body increments, so a block is
propagated with one prefix product (log2 n vectorised compositions) instead of a Python loop.

Public: :class:`BlockPropagator`, :func:`with_previous`, :func:`skew`, :func:`coarse_level`,
:func:`from_rph`, :func:`euler_rph`,
:func:`attitude_errors`, :func:`rotation_error_ned`, :func:`gain_weight`, :func:`sequential_update`,
:func:`van_loan`, :func:`expm_small`.

References: thesis (shared/seeds/000_...) eq. 3.6, 3.38-3.45, 3.54-3.56, 3.58-3.60;
paper 001 (shared/seeds/001_...) eq. 46-47.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from workbench.angles import wrap_pi as _wrap


def _prefix_product(m: np.ndarray) -> np.ndarray:
    """Cumulative products ``m[0], m[0] @ m[1], ..., m[0] @ ... @ m[n-1]`` of (n, 3, 3) matrices.

    A Hillis-Steele scan: log2(n) vectorised matrix products.
    """
    m = np.array(m)
    s = 1
    while s < len(m):
        m[s:] = m[:-s] @ m[s:]
        s *= 2
    return m


class BlockPropagator:
    """Propagates body-to-NED direction-cosine matrices over blocks of ``n`` gyro samples.

    ``dt`` sample interval, s; ``earth_rate_ned`` (3,) rad/s. The Earth-rate factor
    ``Exp(-w_ie t_k)`` of each sample in a block is computed once here.
    """

    def __init__(self, n: int, dt: float, earth_rate_ned: np.ndarray):
        self.n, self.dt = n, dt
        self.earth = Rotation.from_rotvec(-np.outer(np.arange(1, n + 1) * dt, earth_rate_ned)).as_matrix()

    def propagate(self, c0: np.ndarray, omega_b: np.ndarray, correction_ned: np.ndarray | None = None) -> np.ndarray:
        """DCMs (n, 3, 3) at the block's ``n`` sample times, from ``c0`` (3, 3) one sample earlier.

        ``omega_b`` (n + 1, 3) rad/s: bias-corrected body rates w.r.t. inertial space at the
        sample before the block and at the block's samples; each interval turns by the
        trapezoidal increment ``(w[k-1] + w[k]) dt / 2`` (the rates are instantaneous samples).
        The last matrix is the attitude at the block's last sample.
        ``correction_ned`` (3,) rad, optional: a filter correction applied first, as
        ``Exp(correction) c0`` (folded into the same scipy call as the gyro increments).
        """
        w = np.asarray(omega_b)
        rotvec = 0.5 * (w[:-1] + w[1:]) * self.dt
        if correction_ned is not None:
            rotvec = np.vstack([c0.T @ correction_ned, rotvec])  # Exp(e) c0 = c0 Exp(c0^T e)
        inc = _prefix_product(Rotation.from_rotvec(rotvec).as_matrix())
        if correction_ned is not None:
            inc = inc[1:]
        return self.earth[: len(w) - 1] @ (c0 @ inc)


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix ``[v]x`` (3, 3): ``skew(a) @ b = a x b``."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def integrated_noise_cross(q: np.ndarray, f_n: np.ndarray, window_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Covariances of the attitude, velocity and position errors with a measurement noise ``v`` made of the
    gyro white noise the attitude has just integrated over the last ``window_s`` s (a ZARUPT's gyro mean).

    ``q`` (3, k) = ``E[dθ vᵀ]`` (rad times the unit of ``v``), the attitude error's share, NED; ``f_n`` (3,)
    NED specific force, m/s². The attitude error drives the velocity error through the tilt,
    ``dv̇ = -[f_n×] dθ``, and the velocity the position; with the noise spread evenly over the window:
    ``E[dv vᵀ] = -[f_n×] q window_s / 2`` (m/s) and ``E[dp vᵀ] = -[f_n×] q window_s² / 6`` (m). The
    Coriolis and Earth-rate terms change these by ``~|w_ie| window_s`` (1e-4 for 1 s), left out.
    """
    tilt = -skew(f_n) @ q
    return q, tilt * (window_s / 2.0), tilt * (window_s ** 2 / 6.0)


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


def gain_weight(mu: float, c0: float, c1: float) -> float:
    """Gain scale factor of a normalised innovation ``mu`` (paper 001 eq. 47, bifactor reduction).

    1 for ``|mu| <= c0``; ``c0 (c1 - |mu|) / (|mu| (c1 - c0))`` for ``c0 < |mu| <= c1`` (the
    printed eq. 47 garbles this numerator; this form is continuous: 1 at c0, 0 at c1); 0 beyond.
    """
    a = abs(mu)
    if a <= c0:
        return 1.0
    if a > c1:
        return 0.0
    return c0 * (c1 - a) / (a * (c1 - c0))


def sequential_update(P: np.ndarray, H: np.ndarray, z: np.ndarray, r: np.ndarray,
                      scaling: tuple[float, float] | None = None,
                      unscaled: np.ndarray | None = None,
                      cross: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Kalman measurement update, one scalar measurement at a time (diagonal R).

    ``P`` (n, n) prior covariance; ``H`` (m, n); ``z`` (m,) innovations of the error state
    (measurement minus prediction at zero error); ``r`` (m,) variances. With ``scaling =
    (c0, c1)`` each gain is scaled by :func:`gain_weight` of its normalised innovation
    (paper 001 eq. 46), except the rows where ``unscaled`` (m,) is True. The covariance uses
    the Joseph form, valid for any (scaled) gain. ``cross`` (n, m): the covariance ``E[δx vᵀ]`` of
    the prior error with the measurement noises, when the noise that drove the state over the last
    step is also in the measurement (a gyro mean the attitude has just integrated); the noises are
    then states of their own, ``[δx; v]`` with covariance ``[[P, cross], [crossᵀ, R]]``, measured
    without noise by ``[H, I]`` (the batch form is Simon, *Optimal State Estimation*, sec. 7.1).
    Returns the posterior covariance, the error-state estimate (n,) and the weights (m,).
    """
    n = P.shape[0]
    if cross is not None:
        m = len(z)
        aug = np.block([[P, cross], [np.asarray(cross).T, np.diag(r)]])
        aug, dx, weights = sequential_update(aug, np.hstack([H, np.eye(m)]), z, np.zeros(m), scaling, unscaled)
        return aug[:n, :n], dx[:n], weights
    eye = np.eye(n)
    if scaling is None:  # no per-measurement weights: one batch update gives the same result
        gain = np.linalg.solve(H @ P @ H.T + np.diag(r), H @ P).T
        ikh = eye - gain @ H
        P = ikh @ P @ ikh.T + (gain * r) @ gain.T
        return 0.5 * (P + P.T), gain @ z, np.ones(len(z))
    dx = np.zeros(n)
    weights = np.ones(len(z))
    for i in range(len(z)):
        h = H[i]
        ph = P @ h
        s = float(h @ ph) + r[i]
        innov = z[i] - h @ dx
        gain = ph / s
        if scaling is not None and not (unscaled is not None and unscaled[i]):
            weights[i] = gain_weight(innov / np.sqrt(s), *scaling)
            gain = gain * weights[i]
        dx = dx + gain * innov
        ikh = eye - np.outer(gain, h)
        P = ikh @ P @ ikh.T + r[i] * np.outer(gain, gain)
    return 0.5 * (P + P.T), dx, weights


def with_previous(x: np.ndarray, i0: int, i1: int) -> np.ndarray:
    """Rows ``i0 - 1 .. i1 - 1`` of ``x`` (the sample before a block and the block), repeating row 0 at the start."""
    return x[max(i0 - 1, 0):i1] if i0 > 0 else np.vstack([x[:1], x[:i1]])


def van_loan(F: np.ndarray, Q: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Transition matrix ``exp(F T)`` and discrete process noise ``int exp(F s) Q exp(F s)^T ds`` over T (Van Loan's method).

    ``F`` (n, n) the continuous system matrix, ``Q`` (n, n) the continuous noise covariance ``G Qc G^T``.
    The exponential is :func:`expm_small`'s.
    """
    n = F.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -F
    M[:n, n:] = Q
    M[n:, n:] = F.T
    E = expm_small(M * T)
    phi = E[n:, n:].T
    qd = phi @ E[:n, n:]
    return phi, 0.5 * (qd + qd.T)


def expm_small(a: np.ndarray, terms: int = 12) -> np.ndarray:
    """Matrix exponential of a small (n, n) matrix: Taylor series after scaling, then squaring.

    ``a`` is scaled by ``2^-s`` to an infinity norm below 0.5, where ``terms`` = 12 Taylor terms
    leave a relative error below ``0.5^13 / 13! ~ 2e-14``, and squared back ``s`` times. Only matrix
    products: ``scipy.linalg.expm``'s Pade solve costs milliseconds on a machine whose BLAS threads
    are oversubscribed, which a covariance analysis doing thousands of them cannot afford.
    """
    norm = float(np.max(np.sum(np.abs(a), axis=1)))
    s = max(0, int(np.ceil(np.log2(norm / 0.5)))) if norm > 0.5 else 0
    x = a / 2.0 ** s
    out = np.eye(len(a))
    term = np.eye(len(a))
    for k in range(1, terms + 1):
        term = term @ x / k
        out = out + term
    for _ in range(s):
        out = out @ out
    return out
