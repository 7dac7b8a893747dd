"""Paper 001's land INS: 20-state error-state EKF with NHC, ZUPT and ZARUPT (shared/seeds/001_...).

Error state (eq. 2, 7), NED: ``δx = [δr (N, E, D m), δv (m/s), δψ (rad), b_a (m/s², body),
b_g (rad/s, body), δw (boresight pitch, yaw rad), δl (lever arm m, platform frame)]``. Position,
velocity, attitude, boresight and lever arm are estimated minus true (``C_est = (I + [δψ×]) C``);
``b_a``, ``b_g`` are the residual biases left in the compensated output (true minus estimated
bias), so that ``C_b^n`` enters F with a plus sign as in eq. 3. The closed-loop reset subtracts the
first group from the solution and adds the biases to the bias estimates.

Dynamics (eq. 1-5, 6-9; the standard local-level error model of Groves ch. 14 with position in
metres):

    δṙ = δv
    δv̇ = -[f^n×] δψ + C_b^n b_a - [(2 ω_ie + ω_en)×] δv + (0, 0, 2g/R δr_D)
    δψ̇ = -[ω_in×] δψ - ∂ω_en/∂v δv - ∂ω_ie/∂r δr + C_b^n b_g
    ḃ_a, ḃ_g: random walks; δw, δl: random constants (small random walk, eq. 6-9)

``G w`` with ``w = [accel white, gyro white, accel bias RW, gyro bias RW]`` (eq. 4-5).

Measurements (sequential scalar updates with the M-estimator gain scaling, eq. 46-47):
* NHC (eq. 24-30): the lateral and vertical platform velocity are zero,
  ``v^p = C_b^p C_n^b v^n - C_b^p [ω_nb^b×] C_p^b l^p`` (eq. 20), rows 2-3 of the Jacobian of eq.
  28-29 in this module's convention (:func:`nhc_jacobian`);
* ZUPT (eq. 31-34): ``z = v̂^n``, ``H = [0 I 0 ...]``;
* ZARUPT (eq. 35-40): the moving average of the compensated gyro rotated into NED minus the Earth
  rate is zero: ``z = Ĉ ω̄ - ω_ie``, ``H = [0, 0, -[ω_ie×], 0, C, 0]``.

The innovation ``z`` is always the prediction minus the measurement, so that ``z = H δx + noise``
and the estimate ``δx̂ = K z`` is subtracted from the solution (the paper writes the same with the
opposite sign of both ``z`` and ``H``, eq. 25, 33, 36).

Validity (eq. 41-45): static when the moving average of |gyro - Earth rate| is below
``xi_gyro`` (41-42), the INS speed is below ``xi_speed`` times its covariance sigma (43), and the
navigation-frame acceleration (44) is below ``xi_acc`` (45); NHC while not static and the
yaw rate and acceleration are below the NHC thresholds (sec. 3.1.2).

Public: :class:`LandInsConfig`, :class:`GradeErrors`, :func:`grade_errors`, :func:`error_dynamics`,
:func:`nhc_jacobian`, :func:`cep`, :func:`covariance_analysis`, :func:`run_land_ins`,
:class:`LandInsResult`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workbench.earth import EARTH_RATE, normal_gravity, radii
from workbench.nav.strapdown import sequential_update, skew

N_STATES = 20
P_, V_, A_, BA, BG, BW, LA = (slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15),
                               slice(15, 17), slice(17, 20))


@dataclass(frozen=True)
class GradeErrors:
    """1-sigma sensor errors and noise densities the filter models (SI, per axis).

    ``accel_bias`` m/s², ``gyro_bias`` rad/s (random constants, initial sigma); ``accel_white``
    m/s/√s, ``gyro_white`` rad/√s; ``accel_bias_rw`` m/s²/√s, ``gyro_bias_rw`` rad/s/√s.
    """

    accel_bias: np.ndarray
    gyro_bias: np.ndarray
    accel_white: np.ndarray
    gyro_white: np.ndarray
    accel_bias_rw: np.ndarray
    gyro_bias_rw: np.ndarray


def grade_errors(spec, bias_correlation_s: float = 3600.0) -> GradeErrors:
    """The errors a grade (``workbench.grades.SensorSpec``) tells the filter: table 3-1's bias and
    noise; the bias random walk ``sqrt(rrw² + B² / τ)`` from the grade's rate random walk and bias
    instability (as ``workbench.nav.compensate.process_noise``)."""
    g, a = spec.specs["gyro"], spec.specs["accel"]

    def rw(ts):
        return np.sqrt(ts.noise.rrw ** 2 + ts.noise.bias_instability ** 2 / bias_correlation_s)

    return GradeErrors(np.asarray(a.bias, float), np.asarray(g.bias, float), a.noise.white, g.noise.white,
                       rw(a), rw(g))


@dataclass(frozen=True)
class LandInsConfig:
    """Filter settings (SI unless named).

    ``update_s`` filter step; measurement sigmas ``nhc_sigma`` m/s, ``zupt_sigma`` m/s,
    ``zarupt_sigma_floor`` rad/s (added to ARW / √window); ``zarupt_window_s`` (eq. 40);
    validity thresholds ``xi_gyro`` rad/s (eq. 42), ``xi_speed`` (eq. 43, 2 = 95 %), ``xi_acc`` m/s²
    (eq. 45), ``nhc_max_rate`` rad/s; gain scaling ``c0``, ``c1`` (eq. 47; None = off); initial
    sigmas ``pos0`` m, ``vel0`` m/s, ``tilt0``, ``yaw0`` rad, ``boresight0`` rad, ``lever0`` m;
    ``boresight_rw`` rad/√s, ``lever_rw`` m/√s; ``states`` 15 or 20.
    """

    update_s: float = 1.0
    nhc_sigma: float = 0.05
    zupt_sigma: float = 0.01
    zarupt_sigma_floor: float = 1e-7
    zarupt_window_s: float = 1.0
    xi_gyro: float = np.radians(0.05)
    xi_speed: float = 2.0
    xi_acc: float = 0.05
    nhc_max_rate: float = np.radians(30.0)
    c0: float | None = 1.0
    c1: float = 6.0
    pos0: float = 1.0
    vel0: float = 0.01
    tilt0: float = np.radians(0.01)
    yaw0: float = np.radians(5.0)
    boresight0: float = np.radians(0.5)
    lever0: float = 0.2
    boresight_rw: float = 1e-7
    lever_rw: float = 1e-5
    states: int = 20


def _skew_n(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices (..., 3, 3) of vectors (..., 3)."""
    k = np.zeros(v.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    k[..., 1, 0], k[..., 2, 0], k[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return k


def error_dynamics(c_bn: np.ndarray, f_n: np.ndarray, v_n: np.ndarray, lat, h,
                   grade: GradeErrors, cfg: LandInsConfig) -> tuple[np.ndarray, np.ndarray]:
    """Continuous ``F`` and ``G Q Gᵀ`` (…, 20, 20) at points of the trajectory (module docstring).

    ``c_bn`` (…, 3, 3), ``f_n``, ``v_n`` (…, 3), ``lat`` rad and ``h`` m (…): one point or a batch.
    """
    lat, h = np.asarray(lat, float), np.asarray(h, float)
    shape = lat.shape
    rm, rn = radii(lat)
    g = normal_gravity(lat, h)
    zero = np.zeros(shape)
    w_ie = EARTH_RATE * np.stack([np.cos(lat), zero, -np.sin(lat)], -1)
    w_en = np.stack([v_n[..., 1] / (rn + h), -v_n[..., 0] / (rm + h), -v_n[..., 1] * np.tan(lat) / (rn + h)], -1)
    F = np.zeros(shape + (N_STATES, N_STATES))
    F[..., P_, V_] = np.eye(3)
    F[..., V_, A_] = -_skew_n(f_n)
    F[..., V_, BA] = c_bn
    F[..., V_, V_] = -_skew_n(2 * w_ie + w_en)
    F[..., 5, 2] = 2 * g / np.sqrt(rm * rn)  # gravity falls with height; the Schuler loop is via ∂ω_en/∂v
    F[..., A_, A_] = -_skew_n(w_ie + w_en)
    F[..., 6, 4] = -1 / (rn + h)  # -∂ω_en/∂v
    F[..., 7, 3] = 1 / (rm + h)
    F[..., 8, 4] = np.tan(lat) / (rn + h)
    F[..., 6, 0] = EARTH_RATE * np.sin(lat) / (rm + h)  # -∂ω_ie/∂r_N
    F[..., 8, 0] = EARTH_RATE * np.cos(lat) / (rm + h)
    F[..., A_, BG] = c_bn
    qd = np.zeros(N_STATES)
    qd[V_] = grade.accel_white ** 2
    qd[A_] = grade.gyro_white ** 2
    qd[BA] = grade.accel_bias_rw ** 2
    qd[BG] = grade.gyro_bias_rw ** 2
    qd[BW] = cfg.boresight_rw ** 2
    qd[LA] = cfg.lever_rw ** 2
    gqg = np.zeros(shape + (N_STATES, N_STATES))
    gqg[..., V_, V_] = (c_bn * qd[V_]) @ np.swapaxes(c_bn, -1, -2)  # C diag(q) Cᵀ
    gqg[..., A_, A_] = (c_bn * qd[A_]) @ np.swapaxes(c_bn, -1, -2)
    idx = np.arange(9, N_STATES)
    gqg[..., idx, idx] = qd[9:]
    return F, gqg


def discretise(F: np.ndarray, gqg: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Second-order transition ``Φ = I + F dt + (F dt)²/2`` and ``Q_k = (Φ GQGᵀ Φᵀ + GQGᵀ) dt / 2`` (eq. 11);
    one (20, 20) pair or a batch (…, 20, 20)."""
    fd = F * dt
    phi = np.eye(F.shape[-1]) + fd + 0.5 * fd @ fd
    return phi, 0.5 * (phi @ gqg @ np.swapaxes(phi, -1, -2) + gqg) * dt


def nhc_jacobian(c_bn: np.ndarray, c_bp: np.ndarray, v_n: np.ndarray, w_nb_b: np.ndarray,
                 lever_p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Predicted platform velocity rows 2-3 (2,) and their Jacobian (2, 20) w.r.t. the error state.

    ``v^p = C_b^p C_n^b v^n - C_b^p [ω_nb^b×] C_p^b l^p`` (eq. 20, l resolved in the platform frame).
    With this module's convention (estimates = truth + errors, ``C_est = (I + [δψ×]) C``,
    ``C_b^p est = (I + [δw×]) C_b^p`` with δw = (0, pitch, yaw)), the first-order terms are
    ``∂/∂δv = C_b^p C_n^b``, ``∂/∂δψ = C_b^p C_n^b [v^n×]`` (C_n^b est = C_n^b (I - [δψ×])),
    ``∂/∂δw = -[v^p×] - C_b^p [ω_nb^b×] C_p^b [l^p×]`` (columns pitch, yaw; the second term, the
    boresight turning the lever-arm velocity, is second order and dropped in the paper),
    ``∂/∂δl = -C_b^p [ω_nb^b×] C_p^b`` — eq. 28-29 in this sign convention (the paper's A* holds
    the pitch/yaw columns of ``[v^p×]``). Checked against finite differences in the tests.
    """
    c_nb = c_bn.T
    m = c_bp @ c_nb
    v_p = m @ v_n - c_bp @ skew(w_nb_b) @ c_bp.T @ lever_p
    H = np.zeros((3, N_STATES))
    H[:, V_] = m
    H[:, A_] = m @ skew(v_n)
    lever_term = c_bp @ skew(w_nb_b) @ c_bp.T
    H[:, BW] = (-skew(v_p) - lever_term @ skew(lever_p))[:, 1:]
    H[:, LA] = -lever_term
    return v_p[1:], H[1:]


def cep(p_nn: np.ndarray, draws: int = 200_000, seed: int = 0) -> float:
    """50 % circular error probable (m) of a zero-mean horizontal error with covariance ``p_nn`` (2, 2).

    Exact for any ellipse: the median radius of ``draws`` samples (relative accuracy ~0.3 %).
    """
    lam = np.clip(np.linalg.eigvalsh(p_nn), 0.0, None)
    z = np.random.default_rng(seed).standard_normal((draws, 2))
    return float(np.median(np.sqrt(z[:, 0] ** 2 * lam[0] + z[:, 1] ** 2 * lam[1])))


def _static_mask(speed: np.ndarray) -> np.ndarray:
    return speed < 1e-3


def covariance_analysis(trajectory, grade: GradeErrors, cfg: LandInsConfig = LandInsConfig(),
                        static: np.ndarray | None = None) -> dict:
    """P propagation only along a true trajectory (``workbench.sim.trajectory.Trajectory``), updates
    at every filter step: ZUPT + ZARUPT where the vehicle stands still, NHC while it moves.

    The trajectory is sampled at ``cfg.update_s`` (it may be generated at that rate). Returns
    ``t`` (M,) s, ``sigma`` (M, 20), ``cep_m`` at the end, ``p_end`` (20, 20) and ``heading_change_deg``
    (total absolute heading change while moving).
    """
    tr = trajectory
    dt_tr = tr.t[1] - tr.t[0]
    k = max(1, int(round(cfg.update_s / dt_tr)))
    idx = np.arange(0, len(tr.t), k)
    dt = k * dt_tr
    P = np.diag(_initial_sigma(grade, cfg) ** 2)
    w_ie_all = EARTH_RATE * np.stack([np.cos(tr.lat), 0 * tr.lat, -np.sin(tr.lat)], 1)
    f_n = np.einsum("nij,nj->ni", tr.c_bn, tr.f_b)
    still = _static_mask(tr.speed) if static is None else static
    sig = np.empty((len(idx), N_STATES))
    c_bp = np.eye(3)
    zr = np.zeros(3)
    eye3 = np.eye(3)
    r_zarupt = (grade.gyro_white / np.sqrt(cfg.zarupt_window_s) + cfg.zarupt_sigma_floor) ** 2
    F_all, gqg_all = error_dynamics(tr.c_bn[idx], f_n[idx], tr.v_ned[idx], tr.lat[idx], tr.h[idx], grade, cfg)
    phi_all, q_all = discretise(F_all, gqg_all, dt)
    for j, i in enumerate(idx):
        if j > 0:
            P = phi_all[j] @ P @ phi_all[j].T + q_all[j]
        if still[i]:
            H = np.zeros((6, N_STATES))
            H[:3, V_] = eye3
            H[3:, A_] = -skew(w_ie_all[i])  # ZARUPT: rotated gyro mean minus Earth rate (eq. 38-39)
            H[3:, BG] = tr.c_bn[i]
            r = np.concatenate([np.full(3, cfg.zupt_sigma ** 2), r_zarupt])
        else:
            w_nb_b = tr.omega_ib_b[i] - tr.c_bn[i].T @ (w_ie_all[i])
            _, H = nhc_jacobian(tr.c_bn[i], c_bp, tr.v_ned[i], w_nb_b, zr)
            r = np.full(2, cfg.nhc_sigma ** 2)
        P, _, _ = sequential_update(P, H, np.zeros(len(r)), r)
        sig[j] = np.sqrt(np.diag(P))
    moving = ~still
    dpsi = np.abs(np.diff(np.unwrap(tr.heading)))[moving[1:]].sum()
    return {"t": tr.t[idx], "sigma": sig, "p_end": P, "cep_m": cep(P[:2, :2]),
            "heading_change_deg": float(np.degrees(dpsi))}


def _initial_sigma(grade: GradeErrors, cfg: LandInsConfig) -> np.ndarray:
    """Initial 1-sigma of the 20 states."""
    s = np.empty(N_STATES)
    s[P_] = cfg.pos0
    s[V_] = cfg.vel0
    s[A_] = [cfg.tilt0, cfg.tilt0, cfg.yaw0]
    s[BA] = grade.accel_bias
    s[BG] = grade.gyro_bias
    s[BW] = cfg.boresight0
    s[LA] = cfg.lever0
    return np.maximum(s, 1e-12)


@dataclass
class LandInsResult:
    """Filter output at each step (M,): ``t`` s, ``lat``, ``lon`` rad, ``h`` m, ``v_ned`` (M, 3),
    ``rph`` (M, 3) rad, ``sigma`` (M, 20), ``mode`` (M,) 'zupt' | 'nhc' | 'none', ``weights_min`` (M,)
    the smallest M-estimator weight of the step, ``gyro_bias`` / ``accel_bias`` (M, 3),
    ``boresight`` (M, 2) rad, ``lever_arm`` (M, 3) m."""

    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    v_ned: np.ndarray
    rph: np.ndarray
    sigma: np.ndarray
    mode: np.ndarray
    weights_min: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    boresight: np.ndarray
    lever_arm: np.ndarray
    notes: list = field(default_factory=list)


def _c_bp(boresight: np.ndarray) -> np.ndarray:
    """Body-to-platform rotation ``Exp([w×])``, ``w = (0, pitch, yaw)`` rad from the boresight (pitch, yaw):
    the roll boresight is unobservable by NHC (sec. 2.3.1) and not a state. ``C_b^p ≈ I + [w×]``, so
    an error ``δw`` gives ``(I + [δw×]) C_b^p`` as :func:`nhc_jacobian` assumes."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec([0.0, boresight[0], boresight[1]]).as_matrix()


def run_land_ins(samples, lat0: float, lon0: float, h0: float, heading0: float, grade: GradeErrors,
                 cfg: LandInsConfig = LandInsConfig(), level_s: float = 5.0) -> LandInsResult:
    """Run the filter over body-frame IMU ``samples`` (``ImuSamples``, compensated or raw).

    Start: at rest at (``lat0``, ``lon0`` rad, ``h0`` m) with heading ``heading0`` rad (an external
    or gyrocompassed heading of 1-sigma ``cfg.yaw0``); roll and pitch from the first ``level_s`` s
    (coarse levelling). Every ``cfg.update_s`` the mechanisation (:func:`workbench.nav.ins.mechanise`,
    numba) has run over the step's samples; the covariance is propagated (eq. 11), the validity
    logic chooses ZUPT + ZARUPT or NHC, the sequential update (eq. 46-47) runs and the estimate is
    fed back.
    """
    from workbench.nav.ins import expm_so3, mechanise
    from workbench.nav.strapdown import coarse_level, from_rph

    dt = samples.dt
    n = len(samples.t)
    k_level = max(1, int(round(level_s / dt)))
    roll, pitch = coarse_level(samples.accel[:k_level])
    c = from_rph(roll, pitch, heading0).as_matrix()
    lat, lon, h, v = float(lat0), float(lon0), float(h0), np.zeros(3)
    b_a, b_g = np.zeros(3), np.zeros(3)
    bore, lever = np.zeros(2), np.zeros(3)
    nst = cfg.states
    P = np.diag(_initial_sigma(grade, cfg)[:nst] ** 2)
    step = max(1, int(round(cfg.update_s / dt)))
    m = (n - 1) // step + 1
    out = {k: np.full((m, 3), np.nan) for k in ("pos", "v", "rph", "ba", "bg", "la")}
    sig = np.full((m, N_STATES), np.nan)
    bw_out = np.full((m, 2), np.nan)
    mode = np.empty(m, dtype=object)
    wmin = np.ones(m)
    r_zarupt = (grade.gyro_white / np.sqrt(cfg.zarupt_window_s) + cfg.zarupt_sigma_floor) ** 2
    k_win = max(1, int(round(cfg.zarupt_window_s / dt)))
    scaling = None if cfg.c0 is None else (float(cfg.c0), float(cfg.c1))
    for j in range(m):
        a = j * step
        if j > 0:
            sl = slice(a - step, a + 1)
            gy, ac = samples.gyro[sl] - b_g, samples.accel[sl] - b_a
            nav = mechanise(lat, lon, h, v, c, gy, ac, dt)
            c_prev = c
            lat, lon, h, v, c = float(nav.lat[-1]), float(nav.lon[-1]), float(nav.h[-1]), nav.v_ned[-1], nav.c_bn[-1]
            f_n = 0.5 * (c_prev + c) @ ac.mean(axis=0)
            F, gqg = error_dynamics(c, f_n, v, lat, h, grade, cfg)
            phi, q = discretise(F[:nst, :nst], gqg[:nst, :nst], step * dt)
            P = phi @ P @ phi.T + q
            # validity (eq. 41-45)
            w_ie = EARTH_RATE * np.array([np.cos(lat), 0.0, -np.sin(lat)])
            gw = gy[-k_win:].mean(axis=0)
            gyro_static = np.linalg.norm(gw - c.T @ w_ie) <= cfg.xi_gyro
            speed_static = np.linalg.norm(v) <= cfg.xi_speed * np.sqrt(P[3, 3] + P[4, 4] + P[5, 5])
            g_n = np.array([0.0, 0.0, float(normal_gravity(lat, h))])
            rm, rn = radii(lat)
            w_en = np.array([v[1] / (rn + h), -v[0] / (rm + h), -v[1] * np.tan(lat) / (rn + h)])
            a_n = f_n + g_n - np.cross(w_en + 2 * w_ie, v)
            acc_static = np.linalg.norm(a_n) <= cfg.xi_acc
            w_nb_b = gw - c.T @ (w_ie + w_en)
            if gyro_static and acc_static and speed_static:
                H = np.zeros((6, nst))
                H[:3, V_] = np.eye(3)
                H[3:, A_] = -skew(w_ie)
                H[3:, BG] = c
                z = np.concatenate([v, c @ gw - w_ie])  # predicted minus measured (0): H δx + noise
                r = np.concatenate([np.full(3, cfg.zupt_sigma ** 2), r_zarupt])
                mode[j] = "zupt"
            elif not gyro_static or not acc_static or np.linalg.norm(v) > 0.5:
                if abs(w_nb_b[2]) > cfg.nhc_max_rate:
                    H = None
                    mode[j] = "none"
                else:
                    c_bp = _c_bp(bore)
                    v_p, Hf = nhc_jacobian(c, c_bp, v, w_nb_b, lever)
                    H, z, r = Hf[:, :nst], v_p, np.full(2, cfg.nhc_sigma ** 2)
                    mode[j] = "nhc"
            else:
                H = None
                mode[j] = "none"
            if H is not None:
                P, dx, wts = sequential_update(P, H, z, r, scaling)
                wmin[j] = float(wts.min())
                dx = np.concatenate([dx, np.zeros(N_STATES - nst)])
                rm, rn = radii(lat)
                lat -= dx[0] / (rm + h)
                lon -= dx[1] / ((rn + h) * np.cos(lat))
                h += dx[2]
                v = v - dx[V_]
                c = expm_so3(-dx[6], -dx[7], -dx[8]) @ c
                b_a, b_g = b_a + dx[BA], b_g + dx[BG]
                bore, lever = bore - dx[BW], lever - dx[LA]
        else:
            mode[j] = "start"
        out["pos"][j] = (lat, lon, h)
        out["v"][j] = v
        out["rph"][j] = (np.arctan2(c[2, 1], c[2, 2]), -np.arcsin(np.clip(c[2, 0], -1.0, 1.0)),
                         np.arctan2(c[1, 0], c[0, 0]))
        out["ba"][j], out["bg"][j], out["la"][j] = b_a, b_g, lever
        bw_out[j] = bore
        sig[j, :nst] = np.sqrt(np.diag(P))
    t = samples.t[np.arange(m) * step]
    return LandInsResult(t, out["pos"][:, 0], out["pos"][:, 1], out["pos"][:, 2], out["v"], out["rph"], sig,
                         mode.astype(str), wmin, out["bg"], out["ba"], bw_out, out["la"])
