"""Paper 001's land-INS error model: states, the error dynamics and the NHC Jacobian (shared/seeds/001_...).

Error state, NED: ``δx = [δr (N, E, D m), δv (m/s), δψ (rad), b_a (m/s², body), b_g (rad/s, body),
δw (boresight pitch, yaw rad), δl (lever arm m, platform frame), δs_g (9), δs_a (9)]``: the 15
states of eq. 2, the boresight and lever arm of eq. 7 (20 states, the paper's filter), then the
"additional error states" the paper adds as random constants for its azimuth analysis (sec. 4.1,
ref. [18]): the gyro's and the accelerometer's scale factor (3) and misalignment (6) each,
``δs = (s_x, s_y, s_z, m_xy, m_xz, m_yx, m_yz, m_zx, m_zy)`` with the residual error ``δM u`` of
the compensated output ``(I - Ŝ)(y - b̂)`` (true minus estimated, like the biases), then the gyro's
and the accelerometer's bias instability ``δβ_g``, ``δβ_a`` (body; up to :data:`MAX_RUNGS` first-order
Gauss-Markov rungs of 3 states each, rung after rung, of :mod:`workbench.nav.bias_model`'s flicker
ladder or its single state, in a filter whose grade gives them a sigma; the bias instability is the
rungs' sum). A filter of ``states`` = 15, 20, 29 or 38 uses the leading block plus those
(:func:`state_index`). Sign
conventions and the equations are in :mod:`workbench.nav.land_ins`.

Public: :data:`N_STATES`, :data:`MAX_RUNGS`, the slices ``P_, V_, A_, BA, BG, BW, LA, SG, SA, GG, GA``, :class:`GradeErrors`,
:func:`grade_errors`, :func:`bias_instability_states`, :func:`in_run_rrw`, :func:`rungs_of`, :class:`LandInsConfig`, :func:`state_index`, :func:`scale_columns`,
:func:`error_dynamics`, :func:`discretise`, :func:`nhc_jacobian`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workbench.earth import EARTH_RATE, normal_gravity, radii
from workbench.nav.bias_model import LADDER_RUNGS, flicker_ladder, gauss_markov_from_allan
from workbench.nav.strapdown import skew

MAX_RUNGS = LADDER_RUNGS  # Gauss-Markov rungs per axis the layout has room for
N_STATES = 38 + 6 * MAX_RUNGS
STATE_COUNTS = (15, 20, 29, 38)
BIAS_MODELS = ("ladder", "gauss_markov", "random_walk")
P_, V_, A_, BA, BG, BW, LA = (slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15),
                               slice(15, 17), slice(17, 20))
SG, SA = slice(20, 29), slice(29, 38)
GG, GA = slice(38, 38 + 3 * MAX_RUNGS), slice(38 + 3 * MAX_RUNGS, N_STATES)  # gyro / accel bias instability rungs


@dataclass(frozen=True)
class GradeErrors:
    """1-sigma sensor errors and noise densities the filter models (SI, per axis).

    ``accel_bias`` m/s², ``gyro_bias`` rad/s (random constants, initial sigma); ``accel_white``
    m/s/√s, ``gyro_white`` rad/√s; ``accel_bias_rw`` m/s²/√s, ``gyro_bias_rw`` rad/s/√s;
    ``gyro_scale``, ``gyro_misalignment``, ``accel_scale``, ``accel_misalignment`` (dimensionless,
    per axis: the diagonal of M and the off-diagonal terms of its row; random constants, the
    initial sigma of the scale-factor states, 0 = not modelled); ``gyro_gm_sigma`` rad/s,
    ``accel_gm_sigma`` m/s² and ``gyro_gm_tau``, ``accel_gm_tau`` s: the bias instability as a sum of
    first-order Gauss-Markov rungs of those steady-state sigmas and correlation times, (rungs, 3) or (3,)
    for one, stored padded to (:data:`MAX_RUNGS`, 3) (sigma 0, time inf: no such state).
    """

    accel_bias: np.ndarray
    gyro_bias: np.ndarray
    accel_white: np.ndarray
    gyro_white: np.ndarray
    accel_bias_rw: np.ndarray
    gyro_bias_rw: np.ndarray
    gyro_scale: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gyro_misalignment: np.ndarray = field(default_factory=lambda: np.zeros(3))
    accel_scale: np.ndarray = field(default_factory=lambda: np.zeros(3))
    accel_misalignment: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gyro_gm_sigma: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gyro_gm_tau: np.ndarray = field(default_factory=lambda: np.full(3, np.inf))
    accel_gm_sigma: np.ndarray = field(default_factory=lambda: np.zeros(3))
    accel_gm_tau: np.ndarray = field(default_factory=lambda: np.full(3, np.inf))

    def __post_init__(self) -> None:
        for t in ("gyro", "accel"):
            sigma, tau = _padded(getattr(self, f"{t}_gm_sigma"), 0.0), _padded(getattr(self, f"{t}_gm_tau"), np.inf)
            object.__setattr__(self, f"{t}_gm_sigma", np.where(sigma > 0, sigma, 0.0))
            object.__setattr__(self, f"{t}_gm_tau", np.where(sigma > 0, tau, np.inf))


def _padded(v, fill: float) -> np.ndarray:
    """``v`` (3,) or (rungs, 3) as (:data:`MAX_RUNGS`, 3), the missing rungs ``fill``."""
    v = np.atleast_2d(np.asarray(v, float))
    if v.shape[0] > MAX_RUNGS or v.shape[1:] != (3,):
        raise ValueError(f"land INS: a bias-instability ladder of shape {v.shape} (at most ({MAX_RUNGS}, 3))")
    return np.vstack([v, np.full((MAX_RUNGS - v.shape[0], 3), fill)])


def grade_errors(spec, bias_correlation_s: float = 3600.0, in_run_bias_s: float | None = None,
                 bias_model: str = "ladder") -> GradeErrors:
    """The errors a grade (``workbench.grades.SensorSpec``) tells the filter: table 3-1's bias,
    scale factor, misalignment and noise. The grade's bias instability ``B``: with ``bias_model``
    ``"ladder"`` the flicker ladder of :func:`workbench.nav.bias_model.flicker_ladder` (three Gauss-Markov
    rungs a decade apart around the grade's Allan minimum) beside the rate random walk; ``"gauss_markov"``
    one state (:func:`workbench.nav.bias_model.gauss_markov_from_allan`: sigma 1.076 B, correlation time
    at the Allan minimum / 1.893); ``"random_walk"`` the bias random walk ``sqrt(rrw² + B² / τ)``, ``τ`` =
    ``bias_correlation_s`` (as ``workbench.nav.compensate.process_noise``).

    ``in_run_bias_s``: the grade's bias (table 3-1's "Bias" / "Rate Bias") is also an in-run
    bias that is drawn anew over that time, a random walk of density ``bias √(2 / in_run_bias_s)``
    added to the above (the rate of a first-order Gauss-Markov bias of that sigma and correlation
    time, for times well below it). Paper 001 drives its bias states with a "bias instability
    noise parameter" (eq. 4-5) whose value table 3-1 does not give: :func:`in_run_rrw` and
    docs/navigation.md, "Table 4-1 and eq. 49".
    """
    g, a = spec.specs["gyro"], spec.specs["accel"]

    def markov(ts):
        n = ts.noise
        return bias_instability_states(bias_model, n.white, n.bias_instability, n.rrw, n.quantization)

    def rw(ts):
        walk = ts.noise.bias_instability ** 2 / bias_correlation_s if bias_model == "random_walk" else 0.0
        return np.sqrt(ts.noise.rrw ** 2 + walk + in_run_rrw(ts.bias, in_run_bias_s) ** 2)

    (sg_g, tau_g), (sg_a, tau_a) = markov(g), markov(a)
    return GradeErrors(np.asarray(a.bias, float), np.asarray(g.bias, float), a.noise.white, g.noise.white,
                       rw(a), rw(g), np.asarray(g.scale_factor, float), np.asarray(g.misalignment, float),
                       np.asarray(a.scale_factor, float), np.asarray(a.misalignment, float),
                       sg_g, tau_g, sg_a, tau_a)


def bias_instability_states(bias_model: str, white, bias_instability, rrw=0.0, quantization=0.0,
                            ramp=0.0) -> tuple[np.ndarray, np.ndarray]:
    """(sigma, correlation time) of the Gauss-Markov rungs (rungs, 3) that ``bias_model`` makes of a noise
    block's bias instability (:data:`BIAS_MODELS`; ``"random_walk"``: none). Terms SI, as
    :func:`workbench.nav.bias_model.flicker_ladder`."""
    if bias_model not in BIAS_MODELS:
        raise ValueError(f"land INS: bias_model={bias_model!r} is not one of {', '.join(BIAS_MODELS)}")
    if bias_model == "random_walk":
        return np.zeros(3), np.full(3, np.inf)
    if bias_model == "gauss_markov":
        return gauss_markov_from_allan(white, bias_instability, rrw, quantization, ramp)
    return flicker_ladder(white, bias_instability, rrw, quantization, ramp)


def in_run_rrw(bias: np.ndarray, in_run_bias_s: float | None) -> np.ndarray:
    """Bias random-walk density (SI/√s) that draws a bias of 1-sigma ``bias`` anew over ``in_run_bias_s`` s
    (``bias √(2 / τ)``; zeros for None)."""
    bias = np.asarray(bias, float)
    return np.zeros_like(bias) if in_run_bias_s is None else bias * np.sqrt(2.0 / in_run_bias_s)


@dataclass(frozen=True)
class LandInsConfig:
    """Filter settings (SI unless named).

    ``update_s`` filter step; measurement sigmas ``nhc_sigma`` m/s, ``zupt_sigma`` m/s,
    ``zarupt_sigma_floor`` rad/s (added to ARW / √window); ``zarupt_window_s`` (eq. 40);
    validity thresholds ``xi_gyro`` rad/s (eq. 42), ``xi_speed`` (eq. 43, 2 = 95 %), ``xi_acc`` m/s²
    (eq. 45), ``creep_speed`` m/s (the speed test of eq. 43 passes below it: the gyro and acceleration
    tests decide there, so a velocity error beyond 2 sigma at a stop does not lock ZUPT out for good),
    ``zupt_max_speed`` m/s (and fails above it: on a smooth straight road the gyro and acceleration
    tests pass at constant speed, and an unaided tactical INS's velocity sigma reaches several m/s
    in the hour, so 2 sigma alone let ZUPTs in at 20 m/s),
    ``nhc_max_rate`` rad/s; gain scaling ``c0``, ``c1`` (eq. 47; None = off); initial
    sigmas ``pos0`` m, ``vel0`` m/s, ``tilt0``, ``yaw0`` rad, ``boresight0`` rad, ``lever0`` m (``tilt0``
    is the levelling's own error; the accelerometer bias it absorbs, ``b_a / g``, is added: coarse
    levelling makes the tilt and the horizontal bias cancel, a correlation the filter must carry or
    it believes the bias known to ``tilt0 g`` and loses the stops after the first turn);
    ``boresight_rw`` rad/√s, ``lever_rw`` m/√s; ``states`` 15, 20 (paper 001), 29 (+ the gyro scale
    factor and misalignment) or 38 (+ the accelerometer's too). ``turn_coherence_rad``: a filter without
    the gyro's scale-factor states takes the tilt and heading their errors make in a turn as attitude
    process noise coherent over that rotation angle (:func:`error_dynamics`; None = not modelled).
    """

    update_s: float = 1.0
    nhc_sigma: float = 0.05
    zupt_sigma: float = 0.01
    zarupt_sigma_floor: float = 1e-7
    zarupt_window_s: float = 1.0
    xi_gyro: float = np.radians(0.05)
    xi_speed: float = 2.0
    creep_speed: float = 0.5
    zupt_max_speed: float = 2.0
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
    turn_coherence_rad: float | None = None


def state_index(cfg: LandInsConfig, grade: GradeErrors) -> np.ndarray:
    """Indices (into the :data:`N_STATES` layout) of the states a filter of ``cfg.states`` carries: the leading
    block, then each of the gyro's and the accelerometer's Gauss-Markov bias-instability rungs to which
    ``grade`` gives a sigma."""
    if cfg.states not in STATE_COUNTS:
        raise ValueError(f"land INS: states={cfg.states} is not one of {', '.join(map(str, STATE_COUNTS))}")
    ix = [np.arange(cfg.states)]
    for sigma, sl in ((grade.gyro_gm_sigma, GG), (grade.accel_gm_sigma, GA)):
        for r in np.flatnonzero(np.any(sigma > 0, axis=1)):
            ix.append(np.arange(sl.start + 3 * r, sl.start + 3 * r + 3))
    return np.concatenate(ix)


def rungs_of(m: np.ndarray) -> np.ndarray:
    """``m`` (…, 3, 3) repeated for every rung, (…, 3, 3 :data:`MAX_RUNGS`): the columns of a triad's
    bias-instability rungs, whose sum is the bias instability."""
    return np.concatenate([m] * MAX_RUNGS, axis=-1)


def _skew_n(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices (..., 3, 3) of vectors (..., 3)."""
    k = np.zeros(v.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    k[..., 1, 0], k[..., 2, 0], k[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return k


def scale_columns(u_b: np.ndarray) -> np.ndarray:
    """W(u) (…, 3, 9): the error ``δM u`` of a triad's input ``u`` (…, 3) body frame for the states
    ``(s_x, s_y, s_z, m_xy, m_xz, m_yx, m_yz, m_zx, m_zy)`` (diagonal, then each row's off-diagonal)."""
    w = np.zeros(u_b.shape[:-1] + (3, 9))
    for i in range(3):
        w[..., i, i] = u_b[..., i]
        others = [j for j in range(3) if j != i]
        for k, j in enumerate(others):
            w[..., i, 3 + 2 * i + k] = u_b[..., j]
    return w


def error_dynamics(c_bn: np.ndarray, f_n: np.ndarray, v_n: np.ndarray, lat, h,
                   grade: GradeErrors, cfg: LandInsConfig, omega_b: np.ndarray | None = None,
                   f_b: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Continuous ``F`` and ``G Q Gᵀ`` (…, 44, 44) at points of the trajectory (module docstring).

    ``c_bn`` (…, 3, 3), ``f_n``, ``v_n`` (…, 3), ``lat`` rad and ``h`` m (…): one point or a batch.
    ``omega_b`` (rad/s) and ``f_b`` (m/s²) (…, 3), the body-frame rate and specific force, feed the
    scale-factor states (``δψ̇ += C_b^n W(ω) δs_g``, ``δv̇ += C_b^n W(f) δs_a``); without them those
    columns are zero. Each Gauss-Markov rung of the bias instability enters like the biases (``C_b^n δβ``)
    and decays, ``δβ̇ = -δβ / T + w``, ``E[w²] = 2 σ² / T``. A filter uses the rows and columns of
    :func:`state_index`.

    With ``cfg.turn_coherence_rad`` = θ_c and fewer than 29 states, the gyro's scale factor and misalignment
    (the grade's sigmas Σ_s, not states) turn the rate over the Earth ``ω = ω_ib - C_n^b ω_ie`` into attitude
    error, ``C W(ω) δs``: a random constant, whose error over a turn of angle θ at rate |ω| has the variance
    ``C W Σ_s Wᵀ Cᵀ θ² / |ω|²``. As white attitude noise of density ``C W Σ_s Wᵀ Cᵀ θ_c / |ω|`` it has that
    variance after a turn of θ_c; beyond it the noise form grows as θ where the constant's error is
    bounded (a full turn brings it back), so θ_c is meant for the turns of a pre-calibration, not for an
    hour of constant turning (docs/navigation.md).
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
    F[..., A_, GG] = rungs_of(c_bn)
    F[..., V_, GA] = rungs_of(c_bn)
    F[..., GG, GG] = -np.diag(1.0 / grade.gyro_gm_tau.ravel())
    F[..., GA, GA] = -np.diag(1.0 / grade.accel_gm_tau.ravel())
    if omega_b is not None:
        F[..., A_, SG] = c_bn @ scale_columns(np.asarray(omega_b, float))
    if f_b is not None:
        F[..., V_, SA] = c_bn @ scale_columns(np.asarray(f_b, float))
    qd = np.zeros(N_STATES)
    qd[V_] = grade.accel_white ** 2
    qd[A_] = grade.gyro_white ** 2
    qd[BA] = grade.accel_bias_rw ** 2
    qd[BG] = grade.gyro_bias_rw ** 2
    qd[BW] = cfg.boresight_rw ** 2
    qd[LA] = cfg.lever_rw ** 2
    qd[GG] = (2.0 * grade.gyro_gm_sigma ** 2 / grade.gyro_gm_tau).ravel()
    qd[GA] = (2.0 * grade.accel_gm_sigma ** 2 / grade.accel_gm_tau).ravel()
    turn = 0.0
    if omega_b is not None and cfg.turn_coherence_rad is not None and cfg.states < SG.stop:
        w_nb = np.asarray(omega_b, float) - np.einsum("...ji,...j->...i", c_bn, w_ie)
        rate = np.linalg.norm(w_nb, axis=-1)
        cw = c_bn @ scale_columns(w_nb)
        var_s = np.concatenate([grade.gyro_scale, np.repeat(grade.gyro_misalignment, 2)]) ** 2
        coherence = np.divide(cfg.turn_coherence_rad, rate, out=np.zeros_like(rate), where=rate > 0)
        turn = (cw * var_s) @ np.swapaxes(cw, -1, -2) * coherence[..., None, None]
    gqg = np.zeros(shape + (N_STATES, N_STATES))
    gqg[..., V_, V_] = (c_bn * qd[V_]) @ np.swapaxes(c_bn, -1, -2)  # C diag(q) Cᵀ
    gqg[..., A_, A_] = (c_bn * qd[A_]) @ np.swapaxes(c_bn, -1, -2) + turn
    idx = np.r_[9:20, 38:N_STATES]  # the scale-factor states are random constants (no process noise)
    gqg[..., idx, idx] = qd[idx]
    return F, gqg


def discretise(F: np.ndarray, gqg: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Second-order transition ``Φ = I + F dt + (F dt)²/2`` and ``Q_k = (Φ GQGᵀ Φᵀ + GQGᵀ) dt / 2`` (eq. 11);
    one (n, n) pair or a batch (…, n, n)."""
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
