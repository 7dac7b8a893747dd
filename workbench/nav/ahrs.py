"""Attitude and heading reference: gyro propagation with accelerometer and magnetometer aiding.

Paper 004 (shared/seeds/004_...): attitude from integrated gyros drifts; roll and pitch are
held by the accelerometers (gravity), heading by the tilt-compensated magnetometer, and a
Kalman filter smooths the result. Two filters share one mechanisation and one measurement
model and differ only in how they weigh the measurements:

- :func:`complementary` fixed-gain second-order loops (proportional attitude correction,
  integral gyro-bias correction, critically damped with time constants ``tau_*``);
- :func:`kalman` an error-state Kalman filter with states ``[dtheta_NED (rad), db_g (rad/s)]``,
  process noise from the set's noise block (gyro ARW, bias random walk) and measurement noise
  from the accelerometer VRW and the magnetometer white noise.

Mechanisation: the gyro samples (Earth rate removed, thesis eq. 3.6) are integrated at the full
rate; the measurements are formed and the corrections applied every ``update_interval_s`` from
the block's samples, each rotated into NED with its own attitude and averaged:

    tilt:    f_n = mean(C_k f_k);    z_N = -f_E / |f|,  z_E = f_N / |f|      (= dtheta_N, dtheta_E)
    heading: m_n = mean(C_k m_k);    z_D = wrap(atan2(m_E, m_N) - declination)   (= -dtheta_D)

with ``C_true = Exp(dtheta) C_est``. The heading measurement uses the current tilt estimate
(a tilt-compensated compass) and aids the heading only, so a disturbed magnetometer cannot
tilt the attitude (paper 004 sec. 4.1.1, 5).

Public: :class:`AhrsConfig`, :class:`AhrsResult`, :func:`kalman`, :func:`complementary`,
:func:`initial_attitude`, :func:`mag_white_noise`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from workbench.earth import earth_rate_ned
from workbench.errors import AnalysisError
from workbench.nav.compensate import ImuSamples, ProcessNoise
from workbench.nav.strapdown import (BlockPropagator, coarse_level, euler_rph, from_rph, sequential_update, skew,
                                     with_previous)


@dataclass(frozen=True)
class AhrsConfig:
    """Options of the AHRS filters (SI).

    ``update_interval_s`` measurement/correction period; ``declination`` rad (magnetic north
    east of true north); ``tau_tilt_s``, ``tau_heading_s`` time constants of the complementary
    loops; ``gyro_bias_prior`` 1-sigma rad/s of the Kalman filter's initial bias; the noise
    floors (rad) are added in quadrature to the measurement noise derived from the sensors
    (vibration, unmodelled errors); ``accel_error`` (m/s^2) and ``mag_error_ut`` (µT) are the
    1-sigma systematic errors left in the accelerometer and magnetometer samples (e.g. a
    calibration's residual): they enter the tilt and heading measurement noise as
    ``accel_error / |f|`` and ``mag_error_ut / |m_h|``; ``init_s`` data used for the initial attitude.
    """

    update_interval_s: float = 0.1
    declination: float = 0.0
    tau_tilt_s: float = 5.0
    tau_heading_s: float = 20.0
    gyro_bias_prior: float = np.radians(1.0)
    tilt_noise_floor: float = np.radians(0.01)
    heading_noise_floor: float = np.radians(0.05)
    accel_error: float = 0.0
    mag_error_ut: float = 0.0
    init_s: float = 1.0


@dataclass(frozen=True)
class AhrsResult:
    """AHRS output at the E update epochs.

    ``t`` (E,) s; ``attitude`` Rotation (E,) body-to-NED; ``rph`` (E, 3) roll, pitch, heading
    rad; ``attitude_sigma`` (E, 3) 1-sigma of the attitude error about north, east, down, rad
    (NaN for the complementary filter, which has none);
    ``gyro_bias``, ``gyro_bias_sigma`` (E, 3) rad/s body frame; ``filter`` its name.
    """

    t: np.ndarray
    attitude: Rotation
    rph: np.ndarray
    attitude_sigma: np.ndarray
    gyro_bias: np.ndarray
    gyro_bias_sigma: np.ndarray
    filter: str


def mag_white_noise(mag: np.ndarray) -> np.ndarray:
    """Per-axis white-noise 1-sigma (3,) µT of magnetometer samples (N, 3).

    From second differences, which cancel the field's slow change under table rotation:
    ``var(m[k+1] - 2 m[k] + m[k-1]) = 6 sigma^2`` for white noise. The set's noise block has no
    magnetometer terms, so the AHRS takes this figure from the data.
    """
    d2 = np.diff(np.asarray(mag, float), n=2, axis=0)
    return np.std(d2, axis=0) / np.sqrt(6.0)


def initial_attitude(samples: ImuSamples, declination: float, n: int) -> np.ndarray:
    """Body-to-NED DCM (3, 3) one sample before the first (where the filters start), from the first ``n``.

    Roll and pitch from accelerometer levelling, heading from the tilt-compensated magnetometer.

    The accelerometer and magnetometer samples are rotated into the first sample's body frame
    with the integrated gyros before averaging, so the unit may already be turning.
    """
    rel = BlockPropagator(n, samples.dt, np.zeros(3)).propagate(np.eye(3), with_previous(samples.gyro, 0, n))
    f0, m0 = np.einsum("nij,knj->ki", rel, np.stack([samples.accel[:n], samples.mag[:n]])) / n
    roll, pitch = coarse_level(f0)
    m_level = from_rph(roll, pitch, 0.0).apply(m0)
    heading = declination - np.arctan2(m_level[1], m_level[0])
    return from_rph(roll, pitch, heading).as_matrix()


def _measure(att: np.ndarray, accel: np.ndarray, mag: np.ndarray, declination: float):
    """Tilt and heading innovations (3,) ~ (dtheta_N, dtheta_E, -dtheta_D) and |f|, |m_h|."""
    f, m = np.einsum("nij,knj->ki", att, np.stack([accel, mag])) / len(accel)
    fn = np.linalg.norm(f)
    mh = np.hypot(m[0], m[1])
    psi = np.arctan2(m[1], m[0]) - declination
    return np.array([-f[1] / fn, f[0] / fn, (psi + np.pi) % (2 * np.pi) - np.pi]), fn, mh


def _check(samples: ImuSamples, config: AhrsConfig) -> tuple[int, int]:
    if samples.mag is None:
        raise AnalysisError(f"{samples.source}: the AHRS needs magnetometer columns mx, my, mz")
    n_blk = max(1, int(round(config.update_interval_s / samples.dt)))
    n_init = max(1, int(round(config.init_s / samples.dt)))
    if len(samples) < n_init + 2 * n_blk:
        raise AnalysisError(f"{samples.source}: {len(samples)} samples are too few for the AHRS")
    return n_blk, n_init


def _run(samples: ImuSamples, latitude: float, config: AhrsConfig, correct, name: str) -> AhrsResult:
    """Shared loop: propagate each block, measure, let ``correct`` return (dtheta, db, sigmas)."""
    n_blk, n_init = _check(samples, config)
    w_ie = earth_rate_ned(latitude)
    prop = BlockPropagator(n_blk, samples.dt, w_ie)
    c = initial_attitude(samples, config.declination, n_init)
    bg = np.zeros(3)
    dtheta = np.zeros(3)
    out_t, out_c, out_d, out_b, out_s = [], [], [], [], []
    for i0 in range(0, len(samples) - n_blk + 1, n_blk):
        att = prop.propagate(c, with_previous(samples.gyro, i0, i0 + n_blk) - bg, dtheta)
        z, fn, mh = _measure(att, samples.accel[i0:i0 + n_blk], samples.mag[i0:i0 + n_blk], config.declination)
        dtheta, dbg, sig = correct(z, att.mean(axis=0), fn, mh, samples.gyro[i0:i0 + n_blk].mean(axis=0))
        c = att[-1]  # dtheta is applied at the start of the next block
        bg = bg + dbg
        out_t.append(samples.t[i0 + n_blk - 1])
        out_c.append(c)
        out_d.append(dtheta)
        out_b.append(bg.copy())
        out_s.append(sig)
    attitude = Rotation.from_rotvec(np.array(out_d)) * Rotation.from_matrix(np.array(out_c))
    sig = np.array(out_s)
    return AhrsResult(np.array(out_t), attitude, euler_rph(attitude), sig[:, :3], np.array(out_b), sig[:, 3:], name)


def complementary(samples: ImuSamples, latitude: float, config: AhrsConfig = AhrsConfig()) -> AhrsResult:
    """Complementary filter: ``dtheta = k_p T e``, ``b += -T C^T (k_i e)`` with ``e = (z_N, z_E, -z_D)``.

    Per NED axis ``k_p = 2 / tau``, ``k_i = 1 / tau^2`` (a critically damped loop of time
    constant ``tau``: ``tau_tilt_s`` for north/east, ``tau_heading_s`` for down). No covariance:
    its sigmas are NaN (not estimated).
    """
    T = max(1, int(round(config.update_interval_s / samples.dt))) * samples.dt
    tau = np.array([config.tau_tilt_s, config.tau_tilt_s, config.tau_heading_s])
    kp, ki = 2.0 / tau, 1.0 / tau ** 2
    nan6 = np.full(6, np.nan)

    def correct(z, c_mean, fn, mh, w_mean):
        e = np.array([z[0], z[1], -z[2]])
        return kp * T * e, -T * c_mean.T @ (ki * e), nan6

    return _run(samples, latitude, config, correct, "complementary")


def kalman(samples: ImuSamples, noise: ProcessNoise, latitude: float, config: AhrsConfig = AhrsConfig(),
           mag_noise_ut: np.ndarray | None = None, scale_sigma: float = 0.0) -> AhrsResult:
    """Error-state Kalman filter with gyro-bias states (6 states: attitude error NED, gyro bias body).

    Process noise: gyro ARW and bias random walk from ``noise`` (the set's noise block).
    Measurement noise: tilt ``VRW / (g sqrt(T))`` (the block mean of white accelerometer noise),
    heading ``sigma_m / (|m_h| sqrt(n))`` with ``sigma_m`` the magnetometer white noise
    (``mag_noise_ut``, default :func:`mag_white_noise` of the samples), each with its floor.
    ``scale_sigma`` (dimensionless, 1-sigma) is the gyro scale-factor / misalignment error left in
    the samples: it turns into an apparent bias ``dM w`` that jumps whenever the rate changes,
    so each update adds ``(scale_sigma |dw|)^2`` to the bias covariance (dw: change of the mean
    body rate since the previous block).
    """
    n_blk, _ = _check(samples, config)
    T = n_blk * samples.dt
    w_ie = earth_rate_ned(latitude)
    sig_m = float(np.mean(mag_white_noise(samples.mag) if mag_noise_ut is None else mag_noise_ut))
    vrw = float(np.mean(noise.accel_white))
    q_att = np.diag(noise.gyro_white ** 2) * T
    q_b = np.diag(noise.gyro_bias_rw ** 2) * T
    H = np.zeros((3, 6))
    H[0, 0] = H[1, 1] = 1.0
    H[2, 2] = -1.0
    phi = np.eye(6)
    phi[:3, :3] -= skew(w_ie) * T
    state = {"P": np.diag([1e-4, 1e-4, 1e-2, *np.full(3, config.gyro_bias_prior ** 2)])}
    qd = np.zeros((6, 6))

    def correct(z, c_mean, fn, mh, w_mean):
        dw = np.linalg.norm(w_mean - state.get("w", w_mean))
        state["w"] = w_mean
        qd[3:, 3:] = q_b + np.eye(3) * (scale_sigma * dw) ** 2
        phi[:3, 3:] = -c_mean * T
        qd[:3, :3] = c_mean @ q_att @ c_mean.T
        P = phi @ state["P"] @ phi.T + qd
        r_tilt = ((vrw / fn) ** 2 / T + config.tilt_noise_floor ** 2 + (config.accel_error / fn) ** 2)
        r_head = (sig_m ** 2 / (mh ** 2 * n_blk) + config.heading_noise_floor ** 2
                  + (config.mag_error_ut / mh) ** 2)
        P, dx, _ = sequential_update(P, H, z, np.array([r_tilt, r_tilt, r_head]))
        state["P"] = P
        return dx[:3], dx[3:], np.sqrt(np.diag(P))

    return _run(samples, latitude, config, correct, "kalman")
