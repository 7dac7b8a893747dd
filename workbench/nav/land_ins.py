"""Paper 001's land INS: 20-state error-state EKF with NHC, ZUPT and ZARUPT (shared/seeds/001_...).

The states, the error dynamics and the NHC Jacobian are in :mod:`workbench.nav.land_ins_model`
(re-exported here); ``states`` 29 / 38 add the gyro's / both triads' scale-factor and
misalignment states (random constants, :func:`~workbench.nav.land_ins_model.scale_columns`), the
"additional error states" of the paper's sec. 4.1: without them a unit's 1 mrad misalignment turns
a 1 °/s heading rate into 3.6 °/h of bias-like error the 20 states cannot absorb.

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
    δβ̇_g = -δβ_g / T_g + w, δβ̇_a = -δβ_a / T_a + w per rung: the bias instability as a ladder of
    Gauss-Markov states (:mod:`workbench.nav.bias_model`), their sum entering as ``C_b^n Σ δβ`` beside
    the biases (and in the ZARUPT)

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
from workbench.nav.land_ins_model import (  # noqa: F401  (re-exported: the model's public names)
    A_, BA, BG, BW, GA, GG, LA, MAX_RUNGS, N_STATES, P_, SA, SG, STATE_COUNTS, V_, GradeErrors, LandInsConfig,
    discretise, error_dynamics, grade_errors, nhc_jacobian, rungs_of, scale_columns, state_index)
from workbench.nav import nav_results
from workbench.nav.strapdown import integrated_noise_cross, sequential_update, skew


def cep(p_nn: np.ndarray, draws: int = 200_000, seed: int = 0) -> float:
    """50 % circular error probable (m) of a zero-mean horizontal error with covariance ``p_nn`` (2, 2).

    Exact for any ellipse: the median radius of ``draws`` samples (relative accuracy ~0.3 %).
    """
    lam = np.clip(np.linalg.eigvalsh(p_nn), 0.0, None)
    z = np.random.default_rng(seed).standard_normal((draws, 2))
    return float(np.median(np.sqrt(z[:, 0] ** 2 * lam[0] + z[:, 1] ** 2 * lam[1])))


def _static_mask(speed: np.ndarray) -> np.ndarray:
    return speed < 1e-3


# error sources of the budget: initial covariance blocks, process noise blocks (state indices), measurement noise
BUDGET_INITIAL = {"initial position, velocity": (0, 1, 2, 3, 4, 5), "initial tilt + accel bias": (6, 7, 9, 10, 11),
                  "initial heading": (8,), "gyro bias x, y (table 3-1)": (12, 13), "gyro bias z (table 3-1)": (14,),
                  "initial boresight, lever arm": tuple(range(15, 20)), "scale factor, misalignment": tuple(range(20, 38)),
                  "initial bias instability (Gauss-Markov)": tuple(range(GG.start, N_STATES))}
GYRO_WHITE = "ARW (in the attitude and the ZARUPT)"  # one source: the ZARUPT sees the noise the attitude integrates
BUDGET_NOISE = {"VRW": (3, 4, 5), GYRO_WHITE: (6, 7, 8), "accel bias random walk": (9, 10, 11),
                "gyro bias random walk": (12, 13, 14), "boresight, lever-arm random walk": tuple(range(15, 20)),
                "gyro bias instability (Gauss-Markov)": tuple(range(GG.start, GG.stop)),
                "accel bias instability (Gauss-Markov)": tuple(range(GA.start, GA.stop))}
BUDGET_MEASUREMENT = ("ZUPT noise", "NHC noise")


def covariance_analysis(trajectory, grade: GradeErrors, cfg: LandInsConfig = LandInsConfig(),
                        static: np.ndarray | None = None, budget: bool = False) -> dict:
    """P propagation only along a true trajectory (``workbench.sim.trajectory.Trajectory``), updates
    at every filter step: ZUPT + ZARUPT where the vehicle stands still, NHC while it moves.

    The trajectory is sampled at ``cfg.update_s`` (it may be generated at that rate). Returns
    ``t`` (M,) s, ``sigma`` (M, N_STATES; NaN for the states the filter does not carry), ``cep_m`` at the end,
    ``p_end`` (n, n) over the filter's states (:func:`state_index`) and ``heading_change_deg``
    (total absolute heading change while moving). With ``budget``, also ``budget``: the final
    covariance split by error source (:data:`BUDGET_INITIAL`, :data:`BUDGET_NOISE`,
    :data:`BUDGET_MEASUREMENT`; each source propagated alone through the filter's own gains, so
    the parts add up to ``p_end``), source -> (nst, nst).
    """
    tr = trajectory
    dt_tr = tr.t[1] - tr.t[0]
    k = max(1, int(round(cfg.update_s / dt_tr)))
    idx = np.arange(0, len(tr.t), k)
    dt = k * dt_tr
    ix = state_index(cfg, grade)
    nst = len(ix)
    sub = np.ix_(ix, ix)
    P = _initial_covariance(grade, cfg, float(tr.heading[0]))[sub]
    w_ie_all = EARTH_RATE * np.stack([np.cos(tr.lat), 0 * tr.lat, -np.sin(tr.lat)], 1)
    f_n = np.einsum("nij,nj->ni", tr.c_bn, tr.f_b)
    still = _static_mask(tr.speed) if static is None else static
    sig = np.full((len(idx), N_STATES), np.nan)
    c_bp = np.eye(3)
    zr = np.zeros(3)
    r_zarupt = (grade.gyro_white / np.sqrt(cfg.zarupt_window_s) + cfg.zarupt_sigma_floor) ** 2
    parts = _budget_parts(P, ix) if budget else {}
    for j, i in enumerate(idx):
        if j % CHUNK == 0:  # the transitions of the next CHUNK steps, batched (the full layout's F is large)
            chunk = idx[j:j + CHUNK]
            F_all, gqg_all = error_dynamics(tr.c_bn[chunk], f_n[chunk], tr.v_ned[chunk], tr.lat[chunk], tr.h[chunk], grade,
                                            cfg, tr.omega_ib_b[chunk], tr.f_b[chunk])
            gqg_all = gqg_all[:, ix][:, :, ix]
            phi_all, q_all = discretise(F_all[:, ix][:, :, ix], gqg_all, dt)
            del F_all
        if j > 0:
            phi = phi_all[j % CHUNK]
            P = phi @ P @ phi.T + q_all[j % CHUNK]
            for name, part in parts.items():
                parts[name] = phi @ part @ phi.T
            for name, states in ((k, v) for k, v in BUDGET_NOISE.items() if k in parts):  # eq. 11: linear in GQGᵀ
                g_s = _block(gqg_all[j % CHUNK], states, ix)
                parts[name] += 0.5 * (phi @ g_s @ phi.T + g_s) * dt
        if still[i]:
            H = _zupt_zarupt_rows(tr.c_bn[i], w_ie_all[i], tr.omega_ib_b[i], ix)
            r = np.concatenate([np.full(3, cfg.zupt_sigma ** 2), r_zarupt])
            cross = _zarupt_cross(tr.c_bn[i], f_n[i], grade, cfg, ix)
            noise = {"ZUPT noise": slice(0, 3), GYRO_WHITE: slice(3, 6)}
        else:
            w_nb_b = tr.omega_ib_b[i] - tr.c_bn[i].T @ (w_ie_all[i])
            _, H = nhc_jacobian(tr.c_bn[i], c_bp, tr.v_ned[i], w_nb_b, zr)
            H = H[:, ix]
            r = np.full(2, cfg.nhc_sigma ** 2)
            cross = np.zeros((nst, 2))
            noise = {"NHC noise": slice(0, 2)}
        if parts:  # one batch gain (the same posterior as the sequential scalar updates without scaling)
            ph = P @ H.T + cross
            gain = np.linalg.solve(H @ P @ H.T + H @ cross + cross.T @ H.T + np.diag(r), ph.T).T
            ikh = np.eye(nst) - gain @ H
            for name, part in parts.items():
                sl = noise.get(name)
                parts[name] = ikh @ part @ ikh.T + ((gain[:, sl] * r[sl]) @ gain[:, sl].T if sl else 0.0)
                if name == GYRO_WHITE and sl is not None:  # e+ = (I - KH) e - K v, v correlated with e
                    c_k = ikh @ cross[:, sl] @ gain[:, sl].T
                    parts[name] -= c_k + c_k.T
        P, _, _ = sequential_update(P, H, np.zeros(len(r)), r, cross=cross)
        sig[j, ix] = np.sqrt(np.diag(P))
    moving = ~still
    dpsi = np.abs(np.diff(np.unwrap(tr.heading)))[moving[1:]].sum()
    out = {"t": tr.t[idx], "sigma": sig, "p_end": P, "cep_m": cep(P[:2, :2]),
           "heading_change_deg": float(np.degrees(dpsi))}
    if budget:
        out["budget"] = parts
    return out


CHUNK = 600  # steps of the covariance analysis whose transitions are computed in one batch


def _block(m: np.ndarray, states: tuple[int, ...], ix: np.ndarray) -> np.ndarray:
    """``m`` (n, n) over the filter's states ``ix`` with all but the rows and columns of ``states`` (indices of
    the full layout; those the filter carries) zeroed."""
    pos = [p for p, k in enumerate(ix) if k in states]
    out = np.zeros_like(m)
    out[np.ix_(pos, pos)] = m[np.ix_(pos, pos)]
    return out


def _budget_parts(P0: np.ndarray, ix: np.ndarray) -> dict[str, np.ndarray]:
    """The starting covariance of every budget source the filter ``ix`` carries: its block of ``P0``, zeros
    for the noises."""
    parts = {name: _block(P0, states, ix) for name, states in BUDGET_INITIAL.items() if set(states) & set(ix)}
    parts.update({name: np.zeros_like(P0) for name, states in BUDGET_NOISE.items() if set(states) & set(ix)})
    parts.update({name: np.zeros_like(P0) for name in BUDGET_MEASUREMENT})
    return parts


def speed_test(speed: float, sigma_v: float, cfg: LandInsConfig) -> bool:
    """Eq. 43 with its two guards: the INS ``speed`` (m/s) passes when it is below ``xi_speed`` times its
    covariance ``sigma_v`` (m/s), always below ``cfg.creep_speed`` and never above ``cfg.zupt_max_speed``."""
    return speed <= min(max(cfg.xi_speed * sigma_v, cfg.creep_speed), cfg.zupt_max_speed)


def _zupt_zarupt_rows(c_bn: np.ndarray, w_ie: np.ndarray, omega_b: np.ndarray, ix: np.ndarray) -> np.ndarray:
    """H (6, len(ix)) of ZUPT (eq. 31-34) and ZARUPT (eq. 35-40; rotated gyro mean minus the Earth rate),
    the latter with the gyro scale-factor and bias-instability states when the filter ``ix`` has them."""
    H = np.zeros((6, N_STATES))
    H[:3, V_] = np.eye(3)
    H[3:, A_] = -skew(w_ie)
    H[3:, BG] = c_bn
    H[3:, GG] = rungs_of(c_bn)
    H[3:, SG] = c_bn @ scale_columns(omega_b)
    return H[:, ix]


def _zarupt_cross(c_bn: np.ndarray, f_n: np.ndarray, grade: GradeErrors, cfg: LandInsConfig,
                  ix: np.ndarray) -> np.ndarray:
    """``E[δx vᵀ]`` (len(ix), 6) of the prior error with the noises of the ZUPT + ZARUPT rows (:func:`_zupt_zarupt_rows`).

    The ZARUPT's noise is the rotated mean ``Ĉ n̄`` of the gyro's white noise over its window (the last
    ``zarupt_window_s`` of the step), and the attitude has just integrated the same samples: the
    attitude error grew by ``Ĉ ∫ n dt`` and the velocity error by ``-[f^n×]`` times its integral. So
    ``E[δψ vᵀ] = Ĉ diag(ARW²) Ĉᵀ`` and ``E[δv vᵀ] = -[f^n×] Ĉ diag(ARW²) Ĉᵀ T_w / 2``. Counted as
    independent, the ZUPT (which sees the tilt the noise drove) and the ZARUPT (which sees the noise)
    would both tell the filter the horizontal rate ``b_E + Ω cos L δψ_D`` that gyrocompassing gives
    the heading from, and its heading sigma would come out up to √2 small (measured before: 1.3-1.5x).
    The ZUPT's own noise is independent of the state.
    """
    m = np.zeros((N_STATES, 6))
    m[A_, 3:], m[V_, 3:], _ = integrated_noise_cross(c_bn @ np.diag(grade.gyro_white ** 2) @ c_bn.T, f_n,
                                                     min(cfg.zarupt_window_s, cfg.update_s))
    return m[ix]


def _initial_covariance(grade: GradeErrors, cfg: LandInsConfig, heading0: float = 0.0) -> np.ndarray:
    """Initial covariance (N_STATES, N_STATES) after coarse levelling at heading ``heading0`` (rad).

    Levelling makes the measured specific force vertical, so the tilt absorbs the horizontal error of the
    accelerometer's output at rest: with ``δv̇ = -[f×] δψ + C e`` and ``f = (0, 0, -g)``, ``δψ_N = -e_E / g``
    and ``δψ_E = e_N / g``, ``e^n = C e``, where ``e = b_a + Σ δβ_a + W(f_b) δs_a`` is the bias, its
    instability rungs and (38 states) the scale factor and misalignment acting on gravity, ``f_b = (0, 0, -g)``
    (``m_xz g``, ``m_yz g``: 1 mrad reads as 1 mg). The tilt gets ``tilt0²`` plus the levelled share, and its
    covariance with those states is carried: without it the zero-velocity updates of the alignment make the
    filter believe the horizontal bias known to ``g tilt0`` (0.17 mg for 0.01°), and the bias a turn
    uncovers drives the velocity beyond the stop detector's 2 sigma (eq. 43).
    """
    P0 = np.diag(_initial_sigma(grade, cfg) ** 2)
    g = 9.80665
    c, s_ = np.cos(heading0), np.sin(heading0)
    rows = np.array([[c, -s_, 0.0], [s_, c, 0.0]])  # N and E rows of a level C_b^n
    e_n = np.zeros((2, N_STATES))  # the levelled horizontal specific-force error e^n in the states
    e_n[:, BA] = rows
    e_n[:, GA] = rungs_of(rows)
    if cfg.states >= SA.stop:
        e_n[:, SA] = rows @ scale_columns(np.array([0.0, 0.0, -g]))
    tilt = np.array([[0.0, -1.0 / g], [1.0 / g, 0.0]]) @ e_n  # (δψ_N, δψ_E) = (-e_E, e_N) / g
    P = P0.copy()
    P[6:8, :] = tilt @ P0
    P[:, 6:8] = P[6:8, :].T
    P[6:8, 6:8] = tilt @ P0 @ tilt.T + cfg.tilt0 ** 2 * np.eye(2)
    return P


def _initial_sigma(grade: GradeErrors, cfg: LandInsConfig) -> np.ndarray:
    """Initial 1-sigma of the N_STATES states (a filter uses those of :func:`state_index`).

    A filter without the accelerometer's scale-factor states (``states`` < 38) takes their action on
    gravity at rest, ``W((0, 0, -g)) δs_a`` (misalignment ``m_xz g``, ``m_yz g`` and scale factor ``s_z g``),
    as bias: on a level road the body-frame gravity does not change, so to such a filter it is one. Its
    variance is added to the accelerometer bias's (1 mrad of the grade reads as 1 mg, table 3-1's bias)."""
    s = np.empty(N_STATES)
    s[P_] = cfg.pos0
    s[V_] = cfg.vel0
    s[A_] = [cfg.tilt0, cfg.tilt0, cfg.yaw0]  # the levelling's share is added by _initial_covariance
    s[BG] = grade.gyro_bias
    s[BW] = cfg.boresight0
    s[LA] = cfg.lever0
    s[SG] = np.concatenate([grade.gyro_scale, np.repeat(grade.gyro_misalignment, 2)])
    s[SA] = np.concatenate([grade.accel_scale, np.repeat(grade.accel_misalignment, 2)])
    on_gravity = 0.0
    if cfg.states < SA.stop:
        w = scale_columns(np.array([0.0, 0.0, -9.80665]))
        on_gravity = (w ** 2) @ s[SA] ** 2
    s[BA] = np.sqrt(grade.accel_bias ** 2 + on_gravity)
    s[GG], s[GA] = grade.gyro_gm_sigma.ravel(), grade.accel_gm_sigma.ravel()  # the rungs start in their steady state
    return np.maximum(s, 1e-12)


@dataclass
class LandInsResult:
    """Filter output at each step (M,): ``t`` s, ``lat``, ``lon`` rad, ``h`` m, ``v_ned`` (M, 3),
    ``rph`` (M, 3) rad, ``sigma`` (M, N_STATES; NaN for the states the filter does not carry), ``mode`` (M,)
    'zupt' | 'nhc' | 'none', ``weights_min`` (M,) the smallest M-estimator weight of the step,
    ``gyro_bias`` / ``accel_bias`` (M, 3) (the random constant plus the Gauss-Markov rungs of the bias instability),
    ``boresight`` (M, 2) rad, ``lever_arm`` (M, 3) m; ``gyro_scale`` / ``accel_scale`` (M, 9) the
    scale-factor and misalignment estimates (:func:`scale_columns` order; zeros without those states);
    ``bias_sigma`` (M, 6) the 1-sigma of ``gyro_bias`` and ``accel_bias`` (the constant and the Gauss-Markov
    parts with their covariance)."""

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
    gyro_scale: np.ndarray | None = None
    accel_scale: np.ndarray | None = None
    bias_sigma: np.ndarray | None = None

    @property
    def warnings(self) -> tuple[str, ...]:
        """One-line notes of the run (the result protocol's ``warnings``)."""
        return tuple(self.notes)

    def to_dict(self) -> dict:
        """The end state, JSON-ready, SI (:func:`workbench.nav.nav_results.land_ins_dict`)."""
        return nav_results.land_ins_dict(self)

    def summary(self) -> list[str]:
        """Lines for people in lab units (:func:`workbench.nav.nav_results.land_ins_summary`)."""
        return nav_results.land_ins_summary(self)


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
    s_g, s_a = np.zeros(9), np.zeros(9)  # scale-factor and misalignment estimates
    beta_g, beta_a = np.zeros((MAX_RUNGS, 3)), np.zeros((MAX_RUNGS, 3))  # bias-instability rungs, rad/s and m/s²
    ix = state_index(cfg, grade)
    nst = len(ix)
    sub = np.ix_(ix, ix)
    P = _initial_covariance(grade, cfg, heading0)[sub]
    step = max(1, int(round(cfg.update_s / dt)))
    decay_g, decay_a = (np.exp(-step * dt / np.asarray(tau, float)) for tau in (grade.gyro_gm_tau, grade.accel_gm_tau))
    m = (n - 1) // step + 1
    out = {k: np.full((m, 3), np.nan) for k in ("pos", "v", "rph", "ba", "bg", "la")}
    out.update({k: np.zeros((m, 9)) for k in ("sg", "sa")})
    sig = np.full((m, N_STATES), np.nan)
    total = np.zeros((6, N_STATES))  # gyro, accel bias = the random constant + the Gauss-Markov rungs
    total[0:3, BG] = total[3:6, BA] = np.eye(3)
    total[0:3, GG] = total[3:6, GA] = rungs_of(np.eye(3))
    total = total[:, ix]
    bias_sig = np.full((m, 6), np.nan)
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
            gy = (samples.gyro[sl] - b_g - beta_g.sum(axis=0)) @ (np.eye(3) - _matrix(s_g)).T
            ac = (samples.accel[sl] - b_a - beta_a.sum(axis=0)) @ (np.eye(3) - _matrix(s_a)).T
            beta_g, beta_a = beta_g * decay_g, beta_a * decay_a  # the estimate follows the process's mean
            nav = mechanise(lat, lon, h, v, c, gy, ac, dt)
            c_prev = c
            lat, lon, h, v, c = float(nav.lat[-1]), float(nav.lon[-1]), float(nav.h[-1]), nav.v_ned[-1], nav.c_bn[-1]
            f_n = 0.5 * (c_prev + c) @ ac.mean(axis=0)
            F, gqg = error_dynamics(c, f_n, v, lat, h, grade, cfg, gy.mean(axis=0), ac.mean(axis=0))
            phi, q = discretise(F[sub], gqg[sub], step * dt)
            P = phi @ P @ phi.T + q
            # validity (eq. 41-45)
            w_ie = EARTH_RATE * np.array([np.cos(lat), 0.0, -np.sin(lat)])
            gw = gy[-k_win:].mean(axis=0)
            gyro_static = np.linalg.norm(gw - c.T @ w_ie) <= cfg.xi_gyro
            speed_static = speed_test(float(np.linalg.norm(v)), float(np.sqrt(P[3, 3] + P[4, 4] + P[5, 5])), cfg)
            g_n = np.array([0.0, 0.0, float(normal_gravity(lat, h))])
            rm, rn = radii(lat)
            w_en = np.array([v[1] / (rn + h), -v[0] / (rm + h), -v[1] * np.tan(lat) / (rn + h)])
            a_n = f_n + g_n - np.cross(w_en + 2 * w_ie, v)
            acc_static = np.linalg.norm(a_n) <= cfg.xi_acc
            w_nb_b = gw - c.T @ (w_ie + w_en)
            if gyro_static and acc_static and speed_static:
                H = _zupt_zarupt_rows(c, w_ie, gw, ix)
                z = np.concatenate([v, c @ gw - w_ie])  # predicted minus measured (0): H δx + noise
                r = np.concatenate([np.full(3, cfg.zupt_sigma ** 2), r_zarupt])
                cross = _zarupt_cross(c, f_n, grade, cfg, ix)
                mode[j] = "zupt"
            elif not gyro_static or not acc_static or np.linalg.norm(v) > 0.5:
                if abs(w_nb_b[2]) > cfg.nhc_max_rate:
                    H = None
                    mode[j] = "none"
                else:
                    c_bp = _c_bp(bore)
                    v_p, Hf = nhc_jacobian(c, c_bp, v, w_nb_b, lever)
                    H, z, r, cross = Hf[:, ix], v_p, np.full(2, cfg.nhc_sigma ** 2), None
                    mode[j] = "nhc"
            else:
                H = None
                mode[j] = "none"
            if H is not None:
                P, dx, wts = sequential_update(P, H, z, r, scaling, cross=cross)
                wmin[j] = float(wts.min())
                dx_ix, dx = dx, np.zeros(N_STATES)
                dx[ix] = dx_ix
                rm, rn = radii(lat)
                lat -= dx[0] / (rm + h)
                lon -= dx[1] / ((rn + h) * np.cos(lat))
                h += dx[2]
                v = v - dx[V_]
                c = expm_so3(-dx[6], -dx[7], -dx[8]) @ c
                b_a, b_g = b_a + dx[BA], b_g + dx[BG]
                bore, lever = bore - dx[BW], lever - dx[LA]
                s_g, s_a = s_g + dx[SG], s_a + dx[SA]
                beta_g, beta_a = beta_g + dx[GG].reshape(MAX_RUNGS, 3), beta_a + dx[GA].reshape(MAX_RUNGS, 3)
        else:
            mode[j] = "start"
        out["pos"][j] = (lat, lon, h)
        out["v"][j] = v
        out["rph"][j] = (np.arctan2(c[2, 1], c[2, 2]), -np.arcsin(np.clip(c[2, 0], -1.0, 1.0)),
                         np.arctan2(c[1, 0], c[0, 0]))
        out["ba"][j], out["bg"][j], out["la"][j] = b_a + beta_a.sum(axis=0), b_g + beta_g.sum(axis=0), lever
        out["sg"][j], out["sa"][j] = s_g, s_a
        bw_out[j] = bore
        sig[j, ix] = np.sqrt(np.diag(P))
        bias_sig[j] = np.sqrt(np.einsum("ij,jk,ik->i", total, P, total))
    t = samples.t[np.arange(m) * step]
    return LandInsResult(t, out["pos"][:, 0], out["pos"][:, 1], out["pos"][:, 2], out["v"], out["rph"], sig,
                         mode.astype(str), wmin, out["bg"], out["ba"], bw_out, out["la"],
                         gyro_scale=out["sg"], accel_scale=out["sa"], bias_sigma=bias_sig)


def _matrix(s: np.ndarray) -> np.ndarray:
    """The 3x3 scale-factor and misalignment matrix of the 9 states (:func:`scale_columns` order)."""
    return np.array([[s[0], s[3], s[4]], [s[5], s[1], s[6]], [s[7], s[8], s[2]]])
