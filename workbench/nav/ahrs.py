"""Attitude and heading reference: gyro propagation with accelerometer and magnetometer aiding.

Paper 004 (shared/seeds/004_...): attitude from integrated gyros drifts; roll and pitch are
held by the accelerometers (gravity), heading by the tilt-compensated magnetometer, and a
Kalman filter smooths the result. Two filters share one mechanisation and one measurement
model and differ only in how they weigh the measurements:

- :func:`complementary` fixed-gain second-order loops (proportional attitude correction,
  integral gyro-bias correction, critically damped with time constants ``tau_*``);
- :func:`kalman` an error-state Kalman filter with states ``[dtheta_NED (rad), db_g (rad/s)]``,
  process noise from the set's noise block (gyro ARW, bias random walk), white measurement noise
  from the accelerometer VRW and the magnetometer white noise, and coloured measurement noise
  from the calibration errors left in the accelerometer and magnetometer samples (constant
  body-frame errors: their tilt and heading errors are correlated in time, not white), carried
  as three Gauss-Markov states fitted to the covariance the set implies.

Mechanisation: the gyro samples (Earth rate removed, thesis eq. 3.6) are integrated at the full
rate; the measurements are formed and the corrections applied every ``update_interval_s`` from
the block's samples, each rotated into NED with its own attitude and averaged:

    tilt:    f_n = mean(C_k f_k);    z_N = -f_E / |f|,  z_E = f_N / |f|      (= dtheta_N, dtheta_E)
    heading: m_n = mean(C_k m_k);    z_D = wrap(atan2(m_E, m_N) - declination)   (= -dtheta_D)

with ``C_true = Exp(dtheta) C_est``. The heading measurement uses the current tilt estimate
(a tilt-compensated compass) and aids the heading only, so a disturbed magnetometer cannot
tilt the attitude (paper 004 sec. 4.1.1, 5).

Magnetic disturbances (a magnet, a motor, steel brought near the unit; paper 004 Fig. 16, 20)
are rejected twice over:

- detection: the block's field in NED, ``|m|`` and dip ``atan2(m_D, |m_h|)``, against the
  reference (``AhrsConfig.mag_reference_norm_ut`` / ``mag_reference_dip``, e.g. the calibration
  set's field norm; by default the first ``init_s`` of data). A deviation beyond
  ``mag_gate_sigma`` times its expected 1-sigma (white noise of the block mean, the residual
  hard and soft iron of the set, and the floors ``mag_norm_floor_ut`` / ``mag_dip_floor``) marks
  the block disturbed: its heading measurement is dropped (weight 0) and the heading is carried
  by the gyros alone, its sigma growing honestly;
- innovation gating (Kalman filter only): the heading row's gain is scaled by the bifactor
  M-estimator of paper 001 eq. 46-47 (``c0``, ``c1`` on the normalised innovation), so a
  disturbance that keeps the norm and dip (a field rotated about the vertical) is refused by its
  heading innovation. A heading refused by the gate for ``mag_reject_max_s`` in a row with an
  undisturbed field is taken unscaled again (the reference may be wrong, not the field).

Public: :class:`AhrsConfig`, :class:`AhrsResult`, :func:`kalman`, :func:`complementary`,
:func:`initial_attitude`, :func:`mag_white_noise`. The options, the result, the mechanisation and
the measurement model both filters share are :mod:`workbench.nav.ahrs_model` (re-exported here);
this module holds the two filters.

References: paper 004 (shared/seeds/004_...) sec. 4.1.1, 5; coloured measurement noise by state
augmentation: A. Gelb (ed.), Applied Optimal Estimation, MIT Press (1974), ch. 4.
"""

from __future__ import annotations

import numpy as np

from workbench.earth import earth_rate_ned
from workbench.nav.ahrs_model import (AhrsConfig, AhrsResult, block_sizes, initial_attitude,  # noqa: F401 (re-exported)
                                      mag_white_noise, residual_sigma, run_blocks)
from workbench.nav.compensate import ImuSamples, ProcessNoise
from workbench.nav.strapdown import sequential_update, skew


def complementary(samples: ImuSamples, latitude: float, config: AhrsConfig = AhrsConfig()) -> AhrsResult:
    """Complementary filter: ``dtheta = k_p T e``, ``b += -T C^T (k_i e)`` with ``e = (z_N, z_E, -z_D)``.

    Per NED axis ``k_p = 2 / tau``, ``k_i = 1 / tau^2`` (a critically damped loop of time
    constant ``tau``: ``tau_tilt_s`` for north/east, ``tau_heading_s`` for down). No covariance:
    its sigmas are NaN (not estimated). A block with a disturbed field (module docstring)
    makes no heading correction; there is no innovation gate (no covariance to scale by).
    """
    T = max(1, int(round(config.update_interval_s / samples.dt))) * samples.dt
    tau = np.array([config.tau_tilt_s, config.tau_tilt_s, config.tau_heading_s])
    kp, ki = 2.0 / tau, 1.0 / tau ** 2
    nan6 = np.full(6, np.nan)

    def correct(z, blk, disturbed):
        e = np.array([z[0], z[1], 0.0 if disturbed else -z[2]])
        return kp * T * e, -T * blk.c_mean.T @ (ki * e), nan6, 0.0 if disturbed else 1.0

    block_sizes(samples, config)  # no magnetometer: the one-line error, before its noise is estimated
    return run_blocks(samples, latitude, config, correct, "complementary", float(np.mean(mag_white_noise(samples.mag))))


# rad: the coloured measurement noise decorrelates as exp(-turn / this) while the unit turns. The
# residual errors make tilt and heading errors that are harmonics of the turn angle; the first
# harmonic's correlation cos(turn) has area 1 rad up to its first zero, which exp(-turn / 1 rad) keeps.
ROTATION_CORRELATION_RAD = 1.0


def kalman(samples: ImuSamples, noise: ProcessNoise, latitude: float, config: AhrsConfig = AhrsConfig(),
           mag_noise_ut: np.ndarray | None = None, scale_sigma: float = 0.0) -> AhrsResult:
    """Error-state Kalman AHRS: attitude error (NED), gyro bias (body) and coloured measurement-noise states.

    Process noise: gyro ARW and bias random walk from ``noise`` (the set's noise block).
    White measurement noise: tilt ``VRW / (g sqrt(T))`` (the block mean of white accelerometer
    noise), heading ``sigma_m / (|m_h| sqrt(n))`` with ``sigma_m`` the magnetometer white noise
    (``mag_noise_ut``, default :func:`mag_white_noise` of the samples), each with its floor.

    Coloured measurement noise: the calibration errors left in the accelerometer and magnetometer
    samples (``config.accel_*_error``, ``config.mag_*_error``; ``p = [db_a, vec dM_a, db_m,
    vec dM_m]``, constant in the body frame, covariance ``Sigma_p``) make tilt and heading errors
    ``e_k = G_k p`` with ``G_k = dz / d(mean_j C_j (db + dM x_j))`` at update ``k``: constant while
    the unit is still, changing only as the attitude turns them, so not white noise. ``e`` (one
    state per tilt / heading measurement with a non-zero residual) is a Gauss-Markov process
    with the covariance the set implies: ``Sigma_k = G_k Sigma_p G_k^T``,
    ``C_k = G_k Sigma_p G_{k-1}^T``, ``e_k = Phi e_{k-1} + w``, ``Phi = rho C_k Sigma_{k-1}^-1``,
    ``Q = Sigma_k - rho Phi C_k^T`` (positive semi-definite, marginal variance exact), with
    ``rho = exp(-turn / ROTATION_CORRELATION_RAD)`` for the angle turned w.r.t. NED over the block
    beyond what the gyro white noise explains (the one-step fit alone would keep the errors
    correlated over many revolutions at a slow rate). At rest ``Phi = I``, ``Q = 0``: an offset
    the filter keeps apart from the gyro drift. The filter has no body-frame error states: it
    does not re-calibrate the sensors.

    ``scale_sigma`` (dimensionless, 1-sigma) is the gyro scale-factor / misalignment error left in
    the samples: it turns into an apparent bias ``dM w`` that jumps whenever the rate changes,
    so each update adds ``(scale_sigma |dw|)^2`` to the bias covariance (dw: change of the mean
    body rate since the previous block).
    """
    n_blk, _ = block_sizes(samples, config)
    T = n_blk * samples.dt
    w_ie = earth_rate_ned(latitude)
    sig_m = float(np.mean(mag_white_noise(samples.mag) if mag_noise_ut is None else mag_noise_ut))
    vrw = float(np.mean(noise.accel_white))
    q_att = np.diag(noise.gyro_white ** 2) * T
    q_b = np.diag(noise.gyro_bias_rw ** 2) * T
    var_p = residual_sigma(config) ** 2
    # a turn the gyro white noise explains is no turn (5 sigma of the angle random walk over a
    # block; the norm of three such axes stays below 4 sigma 99.9 % of the time): the unit is still
    still_turn = 5.0 * float(np.max(noise.gyro_white)) * np.sqrt(T)
    rows = np.nonzero([np.any(var_p[:12] > 0)] * 2 + [np.any(var_p[12:] > 0)])[0]  # measurements with coloured noise
    n_e = len(rows)
    n_x = 6 + n_e
    H = np.zeros((3, n_x))
    H[:, :3] = np.diag([1.0, 1.0, -1.0])
    H[rows, 6 + np.arange(n_e)] = 1.0
    phi = np.eye(n_x)
    phi[:3, :3] -= skew(w_ie) * T
    qd = np.zeros((n_x, n_x))
    g = np.zeros((3, 24))
    jac = np.zeros((2, 3, 12))
    eye_e = np.eye(n_e)
    P0 = np.zeros((n_x, n_x))
    P0[np.diag_indices(6)] = [1e-4, 1e-4, 1e-2, *np.full(3, config.gyro_bias_prior ** 2)]
    state = {"P": P0, "e": np.zeros(n_e), "refused": 0}

    def coloured_noise_step(blk):
        """Set ``phi`` and ``qd`` of the measurement-error states for the step to this block."""
        # d(mean_k C_k (db + dM x_k)) / d[db, vec dM] = [C_mean, outer] (3, 12) per sensor, times
        # d(-f_E/|f|, f_N/|f|) / d f_NED = ([u_E u - e_E], [e_N - u_N u]) / |f| and d atan2(m_E, m_N) / d m_NED
        jac[:, :, :3] = blk.c_mean
        jac[:, :, 3:] = blk.outer.reshape(2, 3, 9)
        u = blk.f / blk.fn
        v = u @ jac[0]
        g[0, :12] = (u[1] * v - jac[0, 1]) / blk.fn
        g[1, :12] = (jac[0, 0] - u[0] * v) / blk.fn
        g[2, 12:] = (blk.m[0] * jac[1, 1] - blk.m[1] * jac[1, 0]) / blk.mh ** 2
        gr = g[rows]
        gs = gr * var_p
        sigma = gs @ gr.T
        if "g" in state:
            rho = np.exp(-max(0.0, blk.turn - still_turn) / ROTATION_CORRELATION_RAD)
            cross = gs @ state["g"].T
            phi[6:, 6:] = rho * cross @ state["sigma_inv"]
            qd[6:, 6:] = sigma - rho * phi[6:, 6:] @ cross.T
        else:
            phi[6:, 6:] = eye_e
            qd[6:, 6:] = sigma
        # (a relative 1e-9 ridge keeps the inverse finite when a residual leaves a direction unexcited)
        state["g"], state["sigma_inv"] = gr, np.linalg.inv(sigma + eye_e * (1e-9 * np.trace(sigma) + 1e-300))

    gate_max = int(np.ceil(config.mag_reject_max_s / T))

    def correct(z, blk, disturbed):
        dw = np.linalg.norm(blk.rate - state.get("w", blk.rate))
        state["w"] = blk.rate
        if n_e:
            coloured_noise_step(blk)
        qd[3:6, 3:6] = q_b + np.eye(3) * (scale_sigma * dw) ** 2
        phi[:3, 3:6] = -blk.c_mean * T
        qd[:3, :3] = blk.c_mean @ q_att @ blk.c_mean.T
        P = phi @ state["P"] @ phi.T + qd
        e = phi[6:, 6:] @ state["e"]
        r_tilt = (vrw / blk.fn) ** 2 / T + config.tilt_noise_floor ** 2
        r_head = sig_m ** 2 / (blk.mh ** 2 * n_blk) + config.heading_noise_floor ** 2
        keep = [0, 1] if disturbed else [0, 1, 2]
        unscaled = np.array([True, True, not config.mag_rejection or state["refused"] >= gate_max])[keep]
        P, dx, w = sequential_update(P, H[keep], (z - H[:, 6:] @ e)[keep], np.array([r_tilt, r_tilt, r_head])[keep],
                                     (config.c0, config.c1), unscaled)
        weight = 0.0 if disturbed else float(w[2])
        state["refused"] = 0 if disturbed or weight > 0.0 else state["refused"] + 1
        state["P"], state["e"] = P, e + dx[6:]  # attitude and bias corrections are fed back, e is kept
        return dx[:3], dx[3:6], np.sqrt(np.diag(P)[:6]), weight

    return run_blocks(samples, latitude, config, correct, "kalman", sig_m)
