"""ZUPT fine alignment: coarse levelling, then a 15-state error-state EKF held at the frozen solution.

The thesis algorithm (shared/seeds/000_..., sec. 3.2-3.3, eq. 3.1-3.67): after a coarse
levelling (roll, pitch from the mean accelerometer output; heading given from outside, e.g.
the table or a north-finding result) the initial position, velocity and attitude are frozen;
the simplified mechanisation (eq. 3.4-3.6, 3.42-3.48) integrates the bias-corrected samples at
the full sample rate, and every ``update_interval_s`` (1 s in the thesis: "every second (that
is 100 steps)") a corrector compares the mechanised state with the frozen one (eq. 3.57) and
feeds the 15-state error estimate back (eq. 3.61-3.67): position, velocity, attitude,
accelerometer and gyro biases. Optionally the zero-angular-rate update of paper 001
(shared/seeds/001_..., eq. 35-39, with the moving average of eq. 40) is added, and each scalar
innovation scales its Kalman gain (paper 001 eq. 46-47, bifactor M-estimator).

Conventions (state them because the thesis mixes signs): the error state is
``dx = [dp_NED (m), dv_NED (m/s), dtheta_NED (rad), db_a (m/s^2), db_g (rad/s)]`` with
``true = estimate + error`` for p, v, biases and ``C_true = Exp(dtheta) C_est`` for attitude.
Position errors are kept in metres north/east/down (the thesis uses latitude, longitude,
height: the same state scaled by the radii of curvature); the position-dependent terms of
F (eq. 3.31, 3.33, 3.36) are proportional to V or Omega/R (< 1e-11 /s at rest) and omitted.
F and G are eq. 3.29-3.30 with these signs; the covariance is propagated over each interval
with the exact (Van Loan) discretisation of F and G Q G^T rather than eq. 3.49's first order,
because the interval is 1 s, not one sample.

Refinements over the thesis, for honest uncertainties:
- the levelled attitude holds the horizontal accelerometer bias (tilt error = bias / g). The
  default measurement set holds the *heading* at the frozen value and leaves the tilt to the
  zero-velocity update, which observes the same tilt / accel-bias combination without tying
  it to the bias at levelling time; the initial covariance carries the levelling correlation
  ``dtheta0 = -S b_a``. The thesis' full attitude hold (``measurements`` with ``attitude``)
  is available and models that dependency (``z = dtheta + S db_a``); it is consistent only
  while the accelerometer bias does not wander during the alignment (with a bias random walk
  its innovations grow and the gain scaling ends up rejecting measurements);
- the Jacobians are evaluated at the frozen solution (first-estimates Jacobians): evaluated at
  the corrected attitude they leak spurious information into the unobservable direction. On a
  table that turns between holds they follow the mechanised attitude through each turn and stay at
  that of the first block of each hold for the rest of the hold: re-linearised at every correction,
  the heading corrections of a hold (degrees, with a gyrocompass or a wide external heading) turned
  the model's ``-C b_a`` as if the table had turned, the filter took that for information on the
  horizontal accelerometer bias and tilt, and pitch / x accel bias came out 1.5-1.6x optimistic
  (6-12x with a small true gyro bias; 20 seeds, docs/navigation.md);
- a wide initial heading (an external heading of 17° 1-sigma or more, or none: the gyrocompass of a
  3 °/h unit is 15° off) breaks a first-order heading error model: early on the corrections swing the
  heading by tens of degrees and the Jacobians follow them (error / sigma 1.3-1.6 at 17°, 2-25 at
  30-180°, docs/navigation.md). Coarse, then fine: unless the heading is held, the error model is
  linearised at a *reference* heading, the closed-form gyrocompass through the record's holds
  (:func:`workbench.nav.gyrocompass.indexed_gyrocompass`: with turns good to about the white-noise
  limit, 2° here; at rest bias-limited) weighted with the external heading's prior. The mechanisation
  starts there and the heading error about it stays in the state (never fed back): the estimate may
  swing, the model is linear in the true error, which is the reference's. The filter's heading prior is
  the external heading as given (its mean the heading error about the reference), or ``NO_HEADING_SIGMA``
  with none; the levelling window's mean gyro output is a ZARUPT-like measurement (the gyrocompass's
  data; its rows carry the levelled tilt, which leaks the vertical Earth rate into the horizontal, and
  the gyro bias). The reference is data, but only a linearisation point: the data enter the filter once;
- at rest from a gyrocompass (no heading held, bias-limited: 15° from 3 °/h) the model still misses the
  second-order Earth rate along north, ``Omega_h (cos e - 1)``, which the filter takes for gyro bias: its
  second moment is added to the reported gyro-bias sigma (:func:`_second_order_rate`; y / x gyro bias
  error / sigma 1.68 / 1.35 without it, 60 seeds), and the heading variance ``v`` reported (and used there) is
  ``v + v²``, the second-order share of ``atan2`` (``E[e²] = v (1 + v)`` for ``e = atan2(y, 1 + x)``,
  ``x, y ~ N(0, v)``; 1.04x the linear sigma at 15°, 1.001x at 2°);
- while the heading is held, the external heading's own uncertainty cannot be reduced by the filter and
  is added to the reported heading sigma;
- the zero angular rate update's noise is the mean of the gyro white noise over its window, which
  the attitude (and through the tilt the velocity and position) has just integrated: its covariance
  with the error state (:func:`_zarupt_cross`) enters the update, which otherwise counts the gyro
  noise twice (once through the ZUPT-observed tilt, once in the ZARUPT) and makes the heading
  sigma up to sqrt(2) small. The window is capped at the update interval, so that consecutive
  ZARUPTs share no samples and the error state is correlated with the current one's noise only.

Public: :class:`ZuptConfig`, :class:`ZuptResult`, :func:`align`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from workbench.earth import earth_rate_ned, gravity_ned
from workbench.errors import AnalysisError
from workbench.nav.compensate import ImuSamples, ProcessNoise
from workbench.nav import nav_results
from workbench.angles import wrap_pi
from workbench.nav.gyrocompass import indexed_gyrocompass
from workbench.nav.strapdown import (BlockPropagator, coarse_level, euler_rph, from_rph, integrated_noise_cross,
                                     sequential_update, skew, van_loan, with_previous)

N_STATES = 15
P, V, A, BA, BG = (slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15))
MEASUREMENTS = ("position", "velocity", "attitude", "heading", "zarupt")
HEADING_SOURCES = ("external", "gyrocompass")
# rad: the heading error's prior about the reference when no heading is given (wider than the circle's
# uniform 104°: the data decide)
NO_HEADING_SIGMA = np.pi


@dataclass(frozen=True)
class ZuptConfig:
    """Options of the ZUPT alignment (SI).

    ``level_s`` coarse-levelling window; ``update_interval_s`` corrector period (thesis: 1 s);
    ``measurements`` any of ``position``, ``velocity``, ``attitude`` (all three angles held at
    the frozen solution, eq. 3.57), ``heading`` (heading only), ``zarupt`` (paper 001 eq. 35-40);
    ``zarupt_window_s`` the moving-average length of eq. 40 (capped at ``update_interval_s``); ``gain_scaling`` with ``c0``, ``c1``
    (eq. 46-47; the paper's c1 = 6, but c0 = 3 rather than its 1: with c0 = 1 a third of
    consistent innovations lose gain and the bias estimates lag); pseudo-measurement 1-sigma
    noises; bias priors (1-sigma, per axis or scalar); ``heading_sigma`` the external heading's 1-sigma, rad;
    ``max_rejections``: a measurement rejected (weight 0) that many corrections in a row is
    taken unscaled at the next one, since the unit is known to be at rest (without this, one
    knock would leave the mechanised velocity beyond c1 for good and the filter would diverge).
    ``heading_source``: ``external`` (the ``heading`` argument of :func:`align`, 1-sigma
    ``heading_sigma``, any width up to none at all, 180°) or ``gyrocompass`` (no external heading: the
    heading is only what the filter observes from the Earth rate, paper 001 eq. 48, through the turns;
    module docstring).
    """

    level_s: float = 5.0
    update_interval_s: float = 1.0
    measurements: tuple[str, ...] = ("position", "velocity", "heading")
    zarupt_window_s: float = 1.0
    gain_scaling: bool = True
    c0: float = 3.0
    c1: float = 6.0
    position_sigma_m: float = 1e-3
    velocity_sigma_mps: float = 1e-3
    attitude_sigma_rad: float = 1e-5
    gyro_bias_prior: float | tuple = 1e-2
    accel_bias_prior: float | tuple = 0.1
    heading_sigma: float = np.radians(0.1)
    max_rejections: int = 3
    heading_source: str = "external"

    def __post_init__(self) -> None:
        unknown = set(self.measurements) - set(MEASUREMENTS)
        if unknown:
            raise AnalysisError(f"zupt: unknown measurement(s) {sorted(unknown)} (known: {', '.join(MEASUREMENTS)})")
        if self.heading_source not in HEADING_SOURCES:
            raise AnalysisError(f"zupt: heading_source {self.heading_source!r} (known: {', '.join(HEADING_SOURCES)})")
        if self.heading_source == "gyrocompass" and {"heading", "attitude"} & set(self.measurements):
            raise AnalysisError("zupt: with no external heading (gyrocompass) the heading cannot be held: drop the "
                                "heading / attitude measurements")
        if not self.update_interval_s > 0 or not self.level_s > 0:
            raise AnalysisError("zupt: level_s and update_interval_s must be positive")


@dataclass(frozen=True)
class ZuptResult:
    """ZUPT alignment history at the corrector epochs (E epochs) and final estimates, SI.

    ``t`` (E,) s; ``rph`` (E, 3) roll, pitch, heading rad after each correction;
    ``attitude_sigma`` (E, 3) 1-sigma of the attitude error about north, east, down, rad (down,
    the heading, includes the external heading's own sigma while the heading is held);
    ``position`` (E, 3) m NED offset from the frozen position; ``velocity`` (E, 3) m/s NED;
    ``accel_bias`` / ``gyro_bias`` (E, 3) body-frame estimates with ``*_sigma`` 1-sigma;
    ``drift_velocity`` (E,) m/s and ``drift_attitude`` (E,) rad: how far the free mechanisation
    moved from the frozen solution over the interval before each correction (``drift_attitude``
    NaN over an interval in which the table turns); ``level_sigma`` (2,) the end 1-sigma, rad, of the
    tilt about north and east relative to the accelerometers' level (``dtheta_NE + S db_a``, what the
    zero-velocity update observes at rest; the tilt itself is known only to the accel-bias prior / g
    until the table turns, see :attr:`tilt_observed`); ``weights``
    (E, m) the gain scale factors of eq. 47; ``attitude`` the body-to-NED Rotation (E,);
    ``initial_rph`` the frozen roll and pitch and the reference heading the mechanisation starts from (the
    external heading while it is held, else the closed-form gyrocompass weighted with an external heading);
    ``t_start`` the EKF start time, s; ``reference_sigma`` rad the closed-form gyrocompass's linearised
    1-sigma (NaN while the heading is held);
    ``drift_noise`` (m/s, rad) the 1-sigma norms of the velocity and attitude that white
    accelerometer and gyro noise alone accumulate over one interval.
    """

    t: np.ndarray
    rph: np.ndarray
    attitude_sigma: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    accel_bias: np.ndarray
    accel_bias_sigma: np.ndarray
    gyro_bias: np.ndarray
    gyro_bias_sigma: np.ndarray
    drift_velocity: np.ndarray
    drift_attitude: np.ndarray
    weights: np.ndarray
    attitude: Rotation
    initial_rph: np.ndarray
    t_start: float
    measurements: tuple[str, ...]
    drift_noise: tuple[float, float]
    level_sigma: np.ndarray
    reference_sigma: float

    @property
    def tilt_observed(self) -> bool:
        """Whether the filter reduced the roll / pitch sigma below half its first value (the turns of the
        table separate the tilt from the horizontal accelerometer bias; at rest they are one quantity)."""
        return bool(np.all(self.attitude_sigma[-1, :2] < 0.5 * self.attitude_sigma[0, :2]))

    @property
    def warnings(self) -> tuple[str, ...]:
        """One-line notes of the run (the result protocol's ``warnings``)."""
        notes = []
        if not self.tilt_observed:
            tilt, level = (np.degrees(self.attitude_sigma[-1, :2]).max(), np.degrees(self.level_sigma).max())
            notes.append(f"roll/pitch not observed apart from the horizontal accelerometer bias (the unit does not "
                         f"turn): their 1-sigma {tilt:.2g}° is that bias's prior / g; the level against the "
                         f"accelerometers is known to {level:.2g}°")
        return tuple(notes)

    def to_dict(self) -> dict:
        """The end state, JSON-ready, SI (:func:`workbench.nav.nav_results.zupt_dict`)."""
        return nav_results.zupt_dict(self)

    def summary(self) -> list[str]:
        """Lines for people in lab units (:func:`workbench.nav.nav_results.zupt_summary`)."""
        return nav_results.zupt_summary(self)

    def convergence_time(self, velocity_tol: float | None = None, attitude_tol: float | None = None) -> float | None:
        """Time (s from the EKF start) after which the free mechanisation stays at rest.

        The thesis' criterion ("until the INS indicates itself to be at rest and non-rotating"):
        from then on, over every interval before a correction, the velocity grows by less than
        ``velocity_tol`` m/s and the attitude moves by less than ``attitude_tol`` rad. By default
        5x ``drift_noise`` (the 1-sigma norm of what white VRW / ARW alone move in one
        interval), so "at rest" means "no drift beyond the sensor noise". None if never.
        """
        v_tol = 5.0 * self.drift_noise[0] if velocity_tol is None else velocity_tol
        a_tol = 5.0 * self.drift_noise[1] if attitude_tol is None else attitude_tol
        ok = (self.drift_velocity < v_tol) & (np.isnan(self.drift_attitude) | (self.drift_attitude < a_tol))
        if not ok[-1]:
            return None
        bad = np.nonzero(~ok)[0]
        k = 0 if len(bad) == 0 else bad[-1] + 1
        return float(self.t[k] - self.t_start)


def _continuous_model(c: np.ndarray, f_n: np.ndarray, w_ie: np.ndarray, noise: ProcessNoise):
    """F (15x15) and G Q G^T (15x15) of thesis eq. 3.24, 3.29-3.30 in this module's sign convention."""
    F = np.zeros((N_STATES, N_STATES))
    F[P, V] = np.eye(3)
    F[V, V] = -2.0 * skew(w_ie)
    F[V, A] = -skew(f_n)
    F[V, BA] = -c
    F[A, A] = -skew(w_ie)
    F[A, BG] = -c
    Q = np.zeros((N_STATES, N_STATES))
    Q[V, V] = c @ np.diag(noise.accel_white ** 2) @ c.T
    Q[A, A] = c @ np.diag(noise.gyro_white ** 2) @ c.T
    Q[BA, BA] = np.diag(noise.accel_bias_rw ** 2)
    Q[BG, BG] = np.diag(noise.gyro_bias_rw ** 2)
    return F, Q


def _second_order_rate(c: np.ndarray, w_ie: np.ndarray, heading_var: float) -> np.ndarray:
    """Covariance (3, 3) (rad/s)², body frame, of the Earth-rate term the first-order heading model leaves out.

    A heading error ``e`` (rad) about the reference turns the horizontal Earth rate ``Omega_h`` north by
    ``e``: the model has its east part ``Omega_h e`` and misses ``Omega_h (cos e - 1)`` along north, a
    constant rate at rest that the filter takes for gyro bias along the body's view of north (``c`` body to
    NED). With ``e ~ N(0, heading_var)``: ``E[(Omega_h e² / 2)²] = 3 Omega_h² heading_var² / 4``. Negligible
    from a heading known to a few degrees (through turns); at rest from a gyrocompass it is the bias's error.
    """
    north = c[0]  # NED north in the body frame
    return 0.75 * (w_ie[0] ** 2 + w_ie[1] ** 2) * heading_var ** 2 * np.outer(north, north)


def _zarupt_cross(c: np.ndarray, f_n: np.ndarray, gyro_white: np.ndarray, window_s: float) -> np.ndarray:
    """``E[dx vᵀ]`` (15, 3): covariance of the error state at a correction with the ZARUPT's noise ``v``.

    The ZARUPT (rows ``H = [.., -Cᵀ[w_ie×], .., -I]``) sees ``v = -n̄``, the mean of the body gyro white
    noise ``n`` (density ``gyro_white`` (3,) rad/√s) over the ``window_s`` s before the correction. The
    same samples drove the attitude error, ``dθ̇ = -C n`` (``c`` body-to-NED over the window), so
    ``E[dθ vᵀ] = C diag(gyro_white²)``, and through the tilt the velocity and the position
    (:func:`workbench.nav.strapdown.integrated_noise_cross`; ``f_n`` NED specific force, m/s²).
    """
    m = np.zeros((N_STATES, 3))
    m[A], m[V], m[P] = integrated_noise_cross(c @ np.diag(np.asarray(gyro_white, float) ** 2), f_n, window_s)
    return m


def align(samples: ImuSamples, noise: ProcessNoise, latitude: float, heading: float | None,
          height: float = 0.0, config: ZuptConfig = ZuptConfig(), still: np.ndarray | None = None) -> ZuptResult:
    """Run the ZUPT fine alignment on ``samples`` (gyro rad/s, accel m/s^2, body frame) of a unit on a table.

    ``latitude`` rad and ``height`` m of the site; ``heading`` rad the external heading of the
    body x axis (clockwise from true north; ignored, may be None, with ``heading_source =
    "gyrocompass"``). The first ``config.level_s`` seconds level the unit (at rest); the EKF runs
    on the rest at the full sample rate, correcting every ``config.update_interval_s``.

    ``still`` (N,) bool: samples at which the unit does not turn (default: all). A table that
    turns the unit about the vertical between holds (paper 001 sec. 4's pre-calibration profile)
    keeps it at zero velocity, so the zero-velocity and position updates hold throughout, while
    the zero angular rate update is applied only to intervals entirely still. With turns, the
    mechanisation follows them with the gyros and the error model's ``-C`` (accelerometer and
    gyro bias into velocity and attitude) is evaluated at the block's mechanised attitude: the
    biases seen in NED change with the turn, which separates the heading error from the gyro
    bias (heading observable without an external heading). The heading / attitude holds need a
    unit that does not turn.
    """
    dt = samples.dt
    n_level = int(round(config.level_s / dt))
    n_blk = int(round(config.update_interval_s / dt))
    n_epochs = (len(samples) - n_level) // n_blk
    if n_level < 1 or n_epochs < 2:
        raise AnalysisError(f"{samples.source}: {len(samples) * dt:.1f} s of data is too short for levelling "
                            f"({config.level_s} s) and two {config.update_interval_s} s ZUPT intervals")
    w_ie = earth_rate_ned(latitude)
    g_n = gravity_ned(latitude, height)
    roll0, pitch0 = coarse_level(samples.accel[:n_level])
    still = np.ones(len(samples), bool) if still is None else np.asarray(still, bool)
    rotating = not bool(np.all(still[n_level:]))
    if not np.all(still[:n_level]):
        raise AnalysisError(f"{samples.source}: the unit turns during the {config.level_s} s levelling window")
    if rotating and {"heading", "attitude"} & set(config.measurements):
        raise AnalysisError(f"{samples.source}: the unit turns: the heading / attitude holds do not apply "
                            "(use position, velocity, zarupt)")
    compass = config.heading_source == "gyrocompass"
    held = bool({"heading", "attitude"} & set(config.measurements))
    ba_prior = np.broadcast_to(np.asarray(config.accel_bias_prior, float), (3,))
    bg_prior = np.broadcast_to(np.asarray(config.gyro_bias_prior, float), (3,))
    # the heading the error model is linearised at (module docstring): the external one while it is held, else
    # the closed-form gyrocompass through the record's holds, weighted with an external heading's prior
    heading_ref, ref_sigma = heading, np.nan
    if not held:
        coarse = indexed_gyrocompass(samples.gyro, samples.accel, still, dt, latitude, noise.gyro_white, bg_prior)
        heading_ref, ref_sigma = coarse.heading, coarse.sigma
        if not compass:
            w = coarse.sigma ** 2 / (coarse.sigma ** 2 + config.heading_sigma ** 2)
            heading_ref = float(wrap_pi(coarse.heading + w * wrap_pi(heading - coarse.heading)))
    c_init = from_rph(roll0, pitch0, heading_ref)
    ci = c_init.as_matrix()
    g_meas = float(np.linalg.norm(samples.accel[:n_level].mean(axis=0)))
    # tilt of the levelled attitude caused by an accelerometer bias b (body): eps0 = S b (module doc)
    S = np.zeros((3, 3))
    S[0], S[1] = -ci[1] / g_meas, ci[0] / g_meas

    Pm = np.zeros((N_STATES, N_STATES))
    Pm[P, P] = np.eye(3) * config.position_sigma_m ** 2
    Pm[V, V] = np.eye(3) * config.velocity_sigma_mps ** 2
    Pm[BA, BA] = np.diag(ba_prior ** 2)
    Pm[BG, BG] = np.diag(bg_prior ** 2)
    Pm[A, A] = S @ Pm[BA, BA] @ S.T + np.eye(3) * config.attitude_sigma_rad ** 2  # dtheta0 = -S b_a
    Pm[A, BA] = -S @ Pm[BA, BA]
    Pm[BA, A] = Pm[A, BA].T
    xh = np.zeros(N_STATES)  # the error-state estimate; only the heading error (about the reference) is carried
    # the external heading's sigma: outside the filter while the heading is held (it cannot reduce it), else the
    # heading error's prior about the reference (none given: NO_HEADING_SIGMA); the levelling window's mean gyro
    # output is then the gyrocompass's measurement of the heading and the gyro bias (a ZARUPT over the window)
    heading_extra = config.heading_sigma if held else 0.0
    f_n = np.array([0.0, 0.0, -g_meas])
    if not held:
        Pm[8, 8] += NO_HEADING_SIGMA ** 2 if compass else config.heading_sigma ** 2
        xh[8] = 0.0 if compass else float(wrap_pi(heading - heading_ref))
        h0 = np.zeros((3, N_STATES))
        h0[:, A], h0[:, BG] = -ci.T @ skew(w_ie), -np.eye(3)
        z0 = -(samples.gyro[:n_level].mean(axis=0) - ci.T @ w_ie)
        Pm, dx, _ = sequential_update(Pm, h0, z0 - h0 @ xh, noise.gyro_white ** 2 / (n_level * dt))
        xh = xh + dx
    phi, qd = van_loan(*_continuous_model(ci, f_n, w_ie, noise), n_blk * dt)
    prop = BlockPropagator(n_blk, dt, w_ie)
    c = ci
    pos, vel = np.zeros(3), np.zeros(3)
    ba, bg = np.zeros(3), np.zeros(3)
    ts = np.arange(1, n_blk + 1) * dt
    e_cor = Rotation.from_rotvec(-2.0 * np.outer(ts, w_ie))  # Coriolis solution E(t) = Exp(-2 w_ie t)
    e_cor_inv = e_cor.inv()
    n_avg = min(n_blk, max(1, int(round(config.zarupt_window_s / dt))))  # no sample in two ZARUPTs
    use = config.measurements
    rejected = {}  # consecutive rejections per measurement (rows)
    widths = {"position": 3, "velocity": 3, "attitude": 3 if "attitude" in use else 1, "zarupt": 3}
    order = [m for m in ("position", "velocity", "attitude", "zarupt")
             if m in use or (m == "attitude" and "heading" in use)]
    starts = np.cumsum([0] + [widths[m] for m in order])
    slots = {m: slice(int(a), int(b)) for m, a, b in zip(order, starts[:-1], starts[1:])}
    n_meas = int(starts[-1])
    hist = {k: [] for k in ("t", "c", "rph_sig", "pos", "vel", "ba", "bas", "bg", "bgs", "dv", "da", "w")}
    c_lin, c_hold = ci, None  # linearisation attitude; that of the current hold (turning tables)
    for k in range(n_epochs):
        i0 = n_level + k * n_blk
        blk = samples.slice(i0, i0 + n_blk)
        # -- predictor / integrator (eq. 3.42-3.48), vectorised over the interval ---------------
        att = prop.propagate(c, with_previous(samples.gyro, i0, i0 + n_blk) - bg)
        a_n = np.einsum("nij,nj->ni", att, blk.accel - ba) + g_n
        vel_k = e_cor.apply(vel + np.cumsum(e_cor_inv.apply(a_n), axis=0) * dt)
        v_prev = np.vstack([vel, vel_k[:-1]])
        pos = pos + np.sum(0.5 * (v_prev + vel_k), axis=0) * dt
        drift_v = float(np.linalg.norm(vel_k[-1] - vel))
        vel, c_prev, c = vel_k[-1], c, att[-1]
        blk_still = bool(np.all(still[i0:i0 + n_blk]))
        drift_a = float(np.arccos(np.clip((np.trace(c @ c_prev.T) - 1.0) / 2.0, -1.0, 1.0))) if blk_still \
            else np.nan  # rotation angle; a turning table's is not drift
        # Jacobians at the frozen solution while the unit does not turn (module docstring); through turns at the
        # block's mechanised attitude while turning, and at the attitude of each hold's first block while it lasts
        if rotating and (not blk_still or c_hold is None):
            c_hold = att[len(att) // 2] if blk_still else None
            c_lin = att[len(att) // 2]
            phi, qd = van_loan(*_continuous_model(c_lin, f_n, w_ie, noise), n_blk * dt)
        elif not rotating:
            c_lin = ci
        Pm = phi @ Pm @ phi.T + qd
        xh = phi @ xh
        # -- corrector (eq. 3.57-3.60, paper 001 eq. 35-40, 46-47) -------------------------------
        rows, z, r, names, cross = [], [], [], [], []
        if "position" in use:
            rows.append(np.hstack([np.eye(3), np.zeros((3, 12))]))
            z.append(-pos)
            r.append(np.full(3, config.position_sigma_m ** 2))
            names.append("position")
            cross.append(np.zeros((N_STATES, 3)))
        if "velocity" in use:
            rows.append(np.hstack([np.zeros((3, 3)), np.eye(3), np.zeros((3, 9))]))
            z.append(-vel)
            r.append(np.full(3, config.velocity_sigma_mps ** 2))
            names.append("velocity")
            cross.append(np.zeros((N_STATES, 3)))
        if "attitude" in use or "heading" in use:
            h = np.zeros((3, N_STATES))
            h[:, A] = np.eye(3)
            h[:, BA] = S
            za = Rotation.from_matrix(ci @ c.T).as_rotvec() - S @ ba
            sel = [0, 1, 2] if "attitude" in use else [2]
            rows.append(h[sel])
            z.append(za[sel])
            r.append(np.full(len(sel), config.attitude_sigma_rad ** 2))
            names.append("attitude")
            cross.append(np.zeros((N_STATES, len(sel))))
        w_window = samples.gyro[i0 + n_blk - n_avg:i0 + n_blk]
        if "zarupt" in use and np.all(still[i0 + n_blk - n_avg:i0 + n_blk]):
            w_avg = np.mean(w_window - bg, axis=0)
            h = np.zeros((3, N_STATES))
            h[:, A] = -c_lin.T @ skew(w_ie)
            h[:, BG] = -np.eye(3)
            rows.append(h)
            z.append(-(w_avg - c.T @ w_ie))  # body-frame form of eq. 38: R diagonal
            r.append(noise.gyro_white ** 2 / (n_avg * dt))
            names.append("zarupt")
            cross.append(_zarupt_cross(c_lin, f_n, noise.gyro_white, n_avg * dt))
        H, zv, rv = np.vstack(rows), np.concatenate(z), np.concatenate(r)
        cv = np.hstack(cross) if "zarupt" in names else None
        unscaled = np.concatenate([rejected.get(nm, np.zeros(len(zz), int)) >= config.max_rejections
                                   for nm, zz in zip(names, z)])
        Pm, dx, w_rows = sequential_update(Pm, H, zv - H @ xh, rv,
                                           (config.c0, config.c1) if config.gain_scaling else None, unscaled, cv)
        xh = xh + dx
        weights = np.full(n_meas, np.nan)
        k_row = 0
        for nm, zz in zip(names, z):
            w_nm = w_rows[k_row:k_row + len(zz)]
            rejected[nm] = np.where(w_nm == 0.0, rejected.get(nm, np.zeros(len(zz), int)) + 1, 0)
            weights[slots[nm]] = w_nm
            k_row += len(zz)
        # -- feedback (eq. 3.61-3.67) -------------------------------------------------------------
        # (all but the heading error, which stays in the state: the mechanisation keeps the reference heading)
        pos, vel = pos + xh[P], vel + xh[V]
        c = Rotation.from_rotvec([xh[6], xh[7], 0.0]).as_matrix() @ c
        ba, bg = ba + xh[BA], bg + xh[BG]
        xh[:8], xh[9:] = 0.0, 0.0
        att_sig = np.sqrt(np.diag(Pm[A, A]))
        heading_var = Pm[8, 8] + Pm[8, 8] ** 2  # with atan2's second-order share (module docstring)
        hist["t"].append(blk.t[-1])
        hist["c"].append(Rotation.from_rotvec([0.0, 0.0, xh[8]]).as_matrix() @ c)
        hist["rph_sig"].append(np.array([att_sig[0], att_sig[1], np.hypot(np.sqrt(heading_var), heading_extra)]))
        hist["pos"].append(pos.copy())
        hist["vel"].append(vel.copy())
        hist["ba"].append(ba.copy())
        hist["bas"].append(np.sqrt(np.diag(Pm[BA, BA])))
        hist["bg"].append(bg.copy())
        hist["bgs"].append(np.sqrt(np.diag(Pm[BG, BG] + _second_order_rate(c, w_ie, heading_var))))
        hist["dv"].append(drift_v)
        hist["da"].append(drift_a)
        hist["w"].append(weights)
    h_level = np.zeros((2, N_STATES))
    h_level[:, 6:8] = np.eye(2)
    h_level[:, BA] = S[:2]
    arr = {k: np.array(v) for k, v in hist.items() if k != "w"}
    att = Rotation.from_matrix(arr["c"])
    return ZuptResult(arr["t"], euler_rph(att), arr["rph_sig"], arr["pos"], arr["vel"], arr["ba"], arr["bas"],
                      arr["bg"], arr["bgs"], arr["dv"], arr["da"], np.array(hist["w"]), att,
                      np.array([roll0, pitch0, heading_ref]), float(samples.t[n_level]), tuple(use),
                      (float(np.linalg.norm(noise.accel_white) * np.sqrt(n_blk * dt)),
                       float(np.linalg.norm(noise.gyro_white) * np.sqrt(n_blk * dt))),
                      np.sqrt(np.diag(h_level @ Pm @ h_level.T)), ref_sigma)
