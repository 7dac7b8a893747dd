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
:func:`initial_attitude`, :func:`mag_white_noise`.

References: paper 004 (shared/seeds/004_...) sec. 4.1.1, 5; coloured measurement noise by state
augmentation: A. Gelb (ed.), Applied Optimal Estimation, MIT Press (1974), ch. 4.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from workbench.angles import wrap_pi
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
    floors (rad) are added in quadrature to the white measurement noise derived from the sensors
    (vibration, unmodelled errors); ``init_s`` data used for the initial attitude.

    Magnetic-disturbance rejection (module docstring): ``mag_rejection`` switches it on;
    ``mag_reference_norm_ut`` µT and ``mag_reference_dip`` rad (None: from the first ``init_s``);
    ``mag_gate_sigma`` the detection threshold in sigmas; ``mag_norm_floor_ut`` µT and
    ``mag_dip_floor`` rad the floors of the expected norm and dip scatter (local gradients, tilt
    errors); ``c0``, ``c1`` the heading gate (paper 001 eq. 47); ``mag_reject_max_s`` s.

    The calibration errors left in the aiding sensors' samples (e.g. a calibration set's
    1-sigma), body frame, per element, scalars broadcast: ``accel_bias_error`` (3,) m/s^2,
    ``accel_scale_error`` (3, 3) dimensionless (of ``M``), ``mag_bias_error_ut`` (3,) µT (hard
    iron), ``mag_scale_error`` (3, 3) (soft iron). They are constant errors, not white noise:
    the Kalman filter carries them as coloured measurement noise (see :func:`kalman`).
    """

    update_interval_s: float = 0.1
    declination: float = 0.0
    tau_tilt_s: float = 5.0
    tau_heading_s: float = 20.0
    gyro_bias_prior: float = np.radians(1.0)
    tilt_noise_floor: float = np.radians(0.01)
    heading_noise_floor: float = np.radians(0.05)
    accel_bias_error: float | np.ndarray = 0.0
    accel_scale_error: float | np.ndarray = 0.0
    mag_bias_error_ut: float | np.ndarray = 0.0
    mag_scale_error: float | np.ndarray = 0.0
    init_s: float = 1.0
    mag_rejection: bool = True
    mag_reference_norm_ut: float | None = None
    mag_reference_dip: float | None = None
    mag_gate_sigma: float = 5.0
    mag_norm_floor_ut: float = 0.3
    mag_dip_floor: float = np.radians(0.3)
    c0: float = 3.0
    c1: float = 6.0
    mag_reject_max_s: float = 30.0


@dataclass(frozen=True)
class AhrsResult:
    """AHRS output at the E update epochs.

    ``t`` (E,) s; ``attitude`` Rotation (E,) body-to-NED; ``rph`` (E, 3) roll, pitch, heading
    rad; ``attitude_sigma`` (E, 3) 1-sigma of the attitude error about north, east, down, rad
    (NaN for the complementary filter, which has none);
    ``gyro_bias``, ``gyro_bias_sigma`` (E, 3) rad/s body frame; ``filter`` its name;
    ``mag_weight`` (E,) the weight the heading measurement got (1 full, 0 refused);
    ``mag_disturbed`` (E,) bool, the field's norm or dip off the reference (module docstring);
    ``mag_reference`` (norm µT, dip rad) the reference used.
    """

    t: np.ndarray
    attitude: Rotation
    rph: np.ndarray
    attitude_sigma: np.ndarray
    gyro_bias: np.ndarray
    gyro_bias_sigma: np.ndarray
    filter: str
    mag_weight: np.ndarray
    mag_disturbed: np.ndarray
    mag_reference: tuple[float, float]

    def disturbed_intervals(self) -> list[tuple[float, float]]:
        """(start, end) s of the runs of update epochs whose field was detected as disturbed."""
        d = np.concatenate([[False], self.mag_disturbed, [False]]).astype(int)
        starts, ends = np.nonzero(np.diff(d) == 1)[0], np.nonzero(np.diff(d) == -1)[0] - 1
        return [(float(self.t[a]), float(self.t[b])) for a, b in zip(starts, ends)]


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
    return _initial(samples, declination, n)[0]


def _initial(samples: ImuSamples, declination: float, n: int) -> tuple[np.ndarray, float, float]:
    """:func:`initial_attitude` and the field's norm (µT) and dip (rad, down positive) over the first ``n``."""
    rel = BlockPropagator(n, samples.dt, np.zeros(3)).propagate(np.eye(3), with_previous(samples.gyro, 0, n))
    f0, m0 = np.einsum("nij,knj->ki", rel, np.stack([samples.accel[:n], samples.mag[:n]])) / n
    roll, pitch = coarse_level(f0)
    m_level = from_rph(roll, pitch, 0.0).apply(m0)
    heading = declination - np.arctan2(m_level[1], m_level[0])
    dip = float(np.arctan2(m_level[2], np.hypot(m_level[0], m_level[1])))
    return from_rph(roll, pitch, heading).as_matrix(), float(np.linalg.norm(m0)), dip


@dataclass(frozen=True)
class _Block:
    """One update block: DCMs ``att`` (n, 3, 3) and their mean ``c_mean``; ``rate`` (3,) rad/s the
    mean bias-corrected body rate, ``turn`` rad the angle turned w.r.t. NED over the block;
    ``outer`` (2, 3, 3, 3) = ``mean_k C_k[:, i] x_k[j]`` for x = accelerometer, magnetometer (body);
    the NED means ``f = mean_k C_k f_k``, ``m = mean_k C_k m_k`` (its diagonal sums), ``|f|``, ``|m_h|``."""

    att: np.ndarray
    c_mean: np.ndarray
    rate: np.ndarray
    turn: float
    outer: np.ndarray
    f: np.ndarray
    m: np.ndarray
    fn: float
    mh: float


def _measure(blk: _Block, declination: float) -> np.ndarray:
    """Tilt and heading innovations (3,) ~ (dtheta_N, dtheta_E, -dtheta_D) of a block."""
    f, m = blk.f, blk.m
    psi = np.arctan2(m[1], m[0]) - declination
    return np.array([-f[1] / blk.fn, f[0] / blk.fn, wrap_pi(psi)])


def _check(samples: ImuSamples, config: AhrsConfig) -> tuple[int, int]:
    if samples.mag is None:
        raise AnalysisError(f"{samples.source}: the AHRS needs magnetometer columns mx, my, mz")
    n_blk = max(1, int(round(config.update_interval_s / samples.dt)))
    n_init = max(1, int(round(config.init_s / samples.dt)))
    if len(samples) < n_init + 2 * n_blk:
        raise AnalysisError(f"{samples.source}: {len(samples)} samples are too few for the AHRS")
    return n_blk, n_init


def _field_gate(config: AhrsConfig, sig_m: float, n_blk: int, ref_norm: float):
    """``disturbed(blk) -> bool``: the block's field norm or dip beyond ``mag_gate_sigma`` of the reference's.

    Expected 1-sigma of a block's norm (µT): the white noise of the block mean, the residual hard
    iron (rms per axis) and soft iron (rms per element times the field) of ``config``, and the
    floor; of its dip: the same over the field magnitude, and the dip floor.
    """
    res = _residual_sigma(config)
    s_mag = np.sqrt(sig_m ** 2 / n_blk + np.mean(res[12:15] ** 2) + np.mean(res[15:] ** 2) * ref_norm ** 2)
    lim_norm = config.mag_gate_sigma * np.hypot(s_mag, config.mag_norm_floor_ut)
    lim_dip = config.mag_gate_sigma * np.hypot(s_mag / ref_norm, config.mag_dip_floor)

    def disturbed(blk: _Block, ref_dip: float) -> bool:
        if not config.mag_rejection:
            return False
        dip = np.arctan2(blk.m[2], blk.mh)
        return bool(abs(np.linalg.norm(blk.m) - ref_norm) > lim_norm or abs(dip - ref_dip) > lim_dip)

    return disturbed


def _run(samples: ImuSamples, latitude: float, config: AhrsConfig, correct, name: str,
         sig_m: float) -> AhrsResult:
    """Shared loop: propagate each block, measure, check the field (``sig_m`` µT white noise per axis),
    let ``correct(z, block, disturbed)`` return (dtheta, db, sigmas, heading weight)."""
    n_blk, n_init = _check(samples, config)
    w_ie = earth_rate_ned(latitude)
    prop = BlockPropagator(n_blk, samples.dt, w_ie)
    c, norm0, dip0 = _initial(samples, config.declination, n_init)
    ref = (norm0 if config.mag_reference_norm_ut is None else float(config.mag_reference_norm_ut),
           dip0 if config.mag_reference_dip is None else float(config.mag_reference_dip))
    disturbed = _field_gate(config, sig_m, n_blk, ref[0])
    bg = np.zeros(3)
    dtheta = np.zeros(3)
    out_t, out_c, out_d, out_b, out_s, out_w, out_x = [], [], [], [], [], [], []
    for i0 in range(0, len(samples) - n_blk + 1, n_blk):
        rates = with_previous(samples.gyro, i0, i0 + n_blk) - bg
        att = prop.propagate(c, rates, dtheta)
        outer = np.einsum("kai,skj->saij", att, np.stack([samples.accel[i0:i0 + n_blk],
                                                          samples.mag[i0:i0 + n_blk]])) / n_blk
        f, m = np.einsum("saii->sa", outer)
        c_mean = att.mean(axis=0)
        rate = rates[1:].mean(axis=0)
        blk = _Block(att, c_mean, rate, float(np.linalg.norm(rate - c_mean.T @ w_ie)) * n_blk * samples.dt,
                     outer, f, m, float(np.linalg.norm(f)), float(np.hypot(m[0], m[1])))
        dist = disturbed(blk, ref[1])
        dtheta, dbg, sig, weight = correct(_measure(blk, config.declination), blk, dist)
        c = att[-1]  # dtheta is applied at the start of the next block
        bg = bg + dbg
        out_t.append(samples.t[i0 + n_blk - 1])
        out_c.append(c)
        out_d.append(dtheta)
        out_b.append(bg.copy())
        out_s.append(sig)
        out_w.append(weight)
        out_x.append(dist)
    attitude = Rotation.from_rotvec(np.array(out_d)) * Rotation.from_matrix(np.array(out_c))
    sig = np.array(out_s)
    return AhrsResult(np.array(out_t), attitude, euler_rph(attitude), sig[:, :3], np.array(out_b), sig[:, 3:], name,
                      np.array(out_w, float), np.array(out_x, bool), ref)


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

    _check(samples, config)  # no magnetometer: the one-line error, before its noise is estimated
    return _run(samples, latitude, config, correct, "complementary", float(np.mean(mag_white_noise(samples.mag))))


def _residual_sigma(config: AhrsConfig) -> np.ndarray:
    """1-sigma (24,) of the residual sensor errors ``[db_a, vec dM_a, db_m, vec dM_m]`` (row-major ``M``)."""
    return np.concatenate([np.broadcast_to(np.asarray(v, float), shape).ravel() for v, shape in (
        (config.accel_bias_error, (3,)), (config.accel_scale_error, (3, 3)),
        (config.mag_bias_error_ut, (3,)), (config.mag_scale_error, (3, 3)))])


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
    n_blk, _ = _check(samples, config)
    T = n_blk * samples.dt
    w_ie = earth_rate_ned(latitude)
    sig_m = float(np.mean(mag_white_noise(samples.mag) if mag_noise_ut is None else mag_noise_ut))
    vrw = float(np.mean(noise.accel_white))
    q_att = np.diag(noise.gyro_white ** 2) * T
    q_b = np.diag(noise.gyro_bias_rw ** 2) * T
    var_p = _residual_sigma(config) ** 2
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

    return _run(samples, latitude, config, correct, "kalman", sig_m)
