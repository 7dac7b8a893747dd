"""AXD-LNS dead reckoning: odometer + z gyro + pitch from the accelerometers, GPS-aided EKF.

Thesis (shared/seeds/000_...) ch. 2, sec. 2.3:

* mechanisation (eq. 2.15-2.18), per IMU sample: heading integrated from the z gyro,
  ``ψ' = (ω_z - b̂ - (C_n^b ω_in^n)_z) / cos θ`` (the Earth and transport rates seen by the
  z axis removed, roll neglected); pitch from the low-passed accelerometers after removing the
  odometer's own acceleration, ``θ = asin(LP(f_x - dv_odo/dt) / g)``; velocity ``v^n = C_b^n
  [v̂, 0, 0]`` with ``v̂ = v_odo (1 + k̂)``; latitude, longitude from eq. 2.17-2.18 (WGS-84 radii);
* error state (eq. 2.20) ``δx = [δd_N, δd_E, δSF, δψ, δBias]`` (m, m, -, rad, rad/s), or the
  4-state variant without ``δSF``; transition eq. 2.21 (first order, ``Δt`` = the filter step,
  ``v_N``, ``v_E`` the step's mean velocity); ``Q`` from the calibration set's noise block: ARW² on
  the heading, the bias random-walk density² on the bias, a scale-factor random walk
  (``sf_random_walk``) and the odometer's white speed noise on the positions;
* GPS update (eq. 2.22-2.26) with the innovation in metres, ``Δn = (φ_GPS - φ̂)(R_M + h)``,
  ``Δe = (λ_GPS - λ̂)(R_N + h) cos φ̂`` (the printed eq. 2.22 divides by the radii; metres need
  the product), ``H = [I_2 0]``, Joseph-form covariance; closed loop: the estimate is fed back
  into the state and zeroed (eq. 2.27);
* initialisation (sec. 2.3.2): position from GPS, z-gyro bias and pitch at rest, heading from the
  GPS course over ground once the odometer speed has stayed above ``cog_speed`` for ``cog_time_s``.
  An external initial heading may be given instead; if the course over ground then disagrees
  with the filter's heading by more than ``3 σ`` (+ 5°), the heading is reset to it and the
  position to the GPS fix (the non-linear reset that recovers a 180° error, thesis Fig. 2.14).
  Fixes whose innovation is beyond ``gate`` sigma are not used: a wrong heading would otherwise
  be explained by the bias and scale-factor states before the reset comes.

Sign conventions: every state is true minus estimated (eq. 2.27, ``x = x⁻ + δx``), except that
eq. 2.21 row 4 (``δψ' = +δBias``) makes ``δBias`` the estimated minus the true bias: the reset
subtracts it. ``δSF`` is the error of the speed correction ``k̂`` (``v_true ≈ v̂ (1 + δSF)``); the
odometer scale-factor error reported is ``s = 1 / (1 + k̂) - 1`` (odometer reads ``(1 + s) v``).

Public: :class:`LnsConfig`, :class:`LnsResult`, :func:`run_lns`, :func:`error_statistics`,
:func:`track_length`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.signal import lfilter

from workbench.angles import wrap_pi as _wrap
from workbench.earth import EARTH_RATE, normal_gravity, radii
from workbench.errors import AnalysisError
from workbench.nav.compensate import ImuSamples, ProcessNoise
from workbench.nav import nav_results


@dataclass(frozen=True)
class LnsConfig:
    """Filter settings (SI).

    ``sf_state``: the 5-state filter of eq. 2.20 (False: the 4-state variant without δSF);
    ``step_s`` filter step; ``gps_sigma`` m (1-sigma per horizontal axis of a fix);
    ``gps_loss_s``: GPS ignored from this time on (the thesis' "SW command"; None = never);
    ``initial_heading``: rad, external initial heading (None: from the course over ground);
    ``cog_speed`` m/s and ``cog_time_s``: course-over-ground initialisation; ``pitch_tau_s``:
    low-pass time constant of the pitch; ``sf_random_walk`` 1/√s (odometer scale factor);
    ``odo_noise`` m/s/√Hz (white speed noise); priors ``sf_sigma`` (-), ``heading_sigma`` rad (of an
    external initial heading), ``bias_sigma`` rad/s (of the at-rest bias, added to its standard
    error); ``bias_at_rest``: measure the z-gyro bias at rest (sec. 2.3.2), else start from 0
    (the calibration set's bias alone); ``reset_gate_deg``: margin of the course-over-ground
    heading reset; ``gate``: a fix whose normalised innovation ``sqrt(z^T S^-1 z)`` exceeds it is
    not used (paper 001's c1 = 6), and after three such fixes in a row the position restarts at the fix.
    """

    sf_state: bool = True
    step_s: float = 1.0
    gps_sigma: float = 3.0
    gps_loss_s: float | None = None
    initial_heading: float | None = None
    cog_speed: float = 3.0
    cog_time_s: float = 5.0
    pitch_tau_s: float = 2.0
    sf_random_walk: float = 2e-3
    odo_noise: float = 0.02
    sf_sigma: float = 0.05
    heading_sigma: float = np.radians(2.0)
    bias_sigma: float = np.radians(1.0) / 3600
    bias_at_rest: bool = True
    reset_gate_deg: float = 5.0
    gate: float = 6.0


@dataclass
class LnsResult:
    """Filter output at each filter step (M,): ``t`` s, ``lat``, ``lon`` rad, ``h`` m, ``heading``,
    ``pitch`` rad, ``speed`` m/s, ``odo_scale`` (estimated odometer scale-factor error, -; NaN in
    the 4-state filter), ``gyro_bias`` rad/s (z), ``sigma`` (M, 5) 1-sigma of ``[d_N, d_E, SF, ψ,
    bias]`` (NaN for a state the variant lacks), ``gps_used`` (M,) bool; ``resets`` (times of the
    course-over-ground heading resets, s), ``t_heading`` (time the heading was first known, s),
    ``notes``."""

    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    heading: np.ndarray
    pitch: np.ndarray
    speed: np.ndarray
    odo_scale: np.ndarray
    gyro_bias: np.ndarray
    sigma: np.ndarray
    gps_used: np.ndarray
    resets: list = field(default_factory=list)
    t_heading: float | None = None
    notes: list = field(default_factory=list)

    @property
    def warnings(self) -> tuple[str, ...]:
        """One-line notes of the run (the result protocol's ``warnings``)."""
        return tuple(self.notes)

    def to_dict(self) -> dict:
        """The end state, JSON-ready, SI (:func:`workbench.nav.nav_results.lns_dict`)."""
        return nav_results.lns_dict(self)

    def summary(self) -> list[str]:
        """Lines for people in lab units (:func:`workbench.nav.nav_results.lns_summary`)."""
        return nav_results.lns_summary(self)


def _course_over_ground(gps: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Course over ground (rad) and ground speed (m/s) of each fix: from ``vn``, ``ve`` if the
    fixes have them, else from the positions of the neighbouring fixes (central differences)."""
    if {"vn", "ve"} <= set(gps.columns):
        vn, ve = gps["vn"].to_numpy(float), gps["ve"].to_numpy(float)
    else:
        t, lat, lon = (gps[c].to_numpy(float) for c in ("t", "lat", "lon"))
        rm, rn = radii(lat)
        vn = np.gradient(lat, t) * rm
        ve = np.gradient(lon, t) * rn * np.cos(lat)
    return np.arctan2(ve, vn), np.hypot(vn, ve)


def run_lns(samples: ImuSamples, odo_distance: np.ndarray, gps: pd.DataFrame | None, latitude: float,
            noise: ProcessNoise, cfg: LnsConfig = LnsConfig()) -> LnsResult:
    """Run the AXD-LNS filter over a drive (see the module docstring).

    ``samples`` body-frame IMU samples (compensated or raw); ``odo_distance`` (N,) m cumulative
    odometer distance at the samples; ``gps`` fixes (t s, lat, lon rad, h m[, vn, ve, vd]) or None;
    ``latitude`` rad (a start value for the Earth rate before the first fix); ``noise`` from
    :func:`workbench.nav.compensate.process_noise`.
    """
    t, dt = samples.t, samples.dt
    n = len(t)
    if len(odo_distance) != n:
        raise AnalysisError(f"{samples.source}: odo_distance has {len(odo_distance)} values for {n} samples")
    if gps is None or len(gps) == 0:
        raise AnalysisError(f"{samples.source}: no GPS fixes: the filter needs at least the initial position")
    sf_on = bool(cfg.sf_state)
    idx = [0, 1, 2, 3, 4] if sf_on else [0, 1, 3, 4]
    ns = len(idx)
    i_psi, i_b = ns - 2, ns - 1
    # odometer speed (per sample) and pitch from the low-passed accelerometers
    dist = np.asarray(odo_distance, float)
    v_odo = np.gradient(dist, t)
    k_smooth = max(1, int(round(0.5 / dt)))
    v_s = np.convolve(v_odo, np.ones(k_smooth) / k_smooth, mode="same")
    a_odo = np.gradient(v_s, t)
    g0 = float(normal_gravity(latitude))
    alpha = np.exp(-dt / cfg.pitch_tau_s)
    fx = samples.accel[:, 0] - a_odo
    fz = samples.accel[:, 2]
    fx_lp, _ = lfilter([1 - alpha], [1, -alpha], fx, zi=[alpha * fx[0]])
    fz_lp, _ = lfilter([1 - alpha], [1, -alpha], fz, zi=[alpha * fz[0]])
    pitch = np.arctan2(fx_lp, -fz_lp)
    # initial rest: the samples before the odometer first moves
    moving = np.nonzero(dist - dist[0] > 0.05)[0]
    k_move = int(moving[0]) if len(moving) else n
    k_rest = max(0, k_move - int(round(1.0 / dt)))
    notes: list[str] = []
    bias0, bias_var0 = 0.0, cfg.bias_sigma ** 2
    if cfg.bias_at_rest:
        if k_rest * dt < 5.0:
            raise AnalysisError(f"{samples.source}: the vehicle rests {k_rest * dt:.1f} s before moving; the z-gyro "
                                "bias and the pitch need at least 5 s at rest (thesis sec. 2.3.2)")
        th0 = float(np.arctan2(np.mean(samples.accel[:k_rest, 0]), -np.mean(samples.accel[:k_rest, 2])))
        w_z = -EARTH_RATE * np.sin(latitude) * np.cos(th0)  # heading-independent part; the rest is ~Ω cos φ sin θ
        bias0 = float(np.mean(samples.gyro[:k_rest, 2]) - w_z)
        se = noise.gyro_white[2] / np.sqrt(k_rest * dt)
        bias_var0 = se ** 2 + cfg.bias_sigma ** 2 + (EARTH_RATE * np.cos(latitude) * abs(np.sin(th0))) ** 2
    gt = gps["t"].to_numpy(float)
    glat, glon, gh = (gps[c].to_numpy(float) for c in ("lat", "lon", "h"))
    cog, gspeed = _course_over_ground(gps)
    use_gps = np.ones(len(gt), bool) if cfg.gps_loss_s is None else gt < cfg.gps_loss_s
    # state
    lat, lon, h = float(glat[0]), float(glon[0]), float(gh[0])
    k_corr = 0.0  # speed correction factor k̂: v̂ = v_odo (1 + k̂)
    bias = bias0
    psi = cfg.initial_heading
    P = np.zeros((ns, ns))
    P[0, 0] = P[1, 1] = cfg.gps_sigma ** 2
    if sf_on:
        P[2, 2] = cfg.sf_sigma ** 2
    P[i_psi, i_psi] = cfg.heading_sigma ** 2
    P[i_b, i_b] = bias_var0
    step = max(1, int(round(cfg.step_s / dt)))
    m = (n - 1) // step + 1
    out = {k: np.full(m, np.nan) for k in ("t", "lat", "lon", "h", "heading", "pitch", "speed", "sf", "bias")}
    sig = np.full((m, 5), np.nan)
    used = np.zeros(m, bool)
    resets: list[float] = []
    t_heading = None if psi is None else float(t[0])
    fast_since: float | None = None
    q_psi, q_b = noise.gyro_white[2] ** 2, noise.gyro_bias_rw[2] ** 2
    g_ptr = 0
    rejected = 0
    for j in range(m):
        a, b = j * step, min(n, (j + 1) * step)
        if j > 0:  # mechanise samples (a - step + 1 .. a]: eq. 2.15-2.18
            sl = slice(a - step + 1, a + 1)
            th = pitch[sl]
            ds = np.diff(dist[a - step:a + 1]) * (1.0 + k_corr)
            rm, rn = radii(lat)
            if psi is not None:
                w_n, w_d = EARTH_RATE * np.cos(lat), -EARTH_RATE * np.sin(lat)
                rate = (samples.gyro[sl, 2] - bias - np.sin(th) * np.cos(psi) * w_n - np.cos(th) * w_d) / np.cos(th)
                psis = psi + np.cumsum(rate) * dt
                ps_mid = psi + (np.cumsum(rate) - 0.5 * rate) * dt
                dn = np.sum(ds * np.cos(th) * np.cos(ps_mid))
                de = np.sum(ds * np.cos(th) * np.sin(ps_mid))
                dh = -np.sum(ds * np.sin(th))
                lat_new = lat + dn / (rm + h)
                lon += de / ((rn + h) * np.cos(0.5 * (lat + lat_new)))
                lat, h, psi = lat_new, h + dh, float(psis[-1])
                T = step * dt
                vn, ve = dn / T, de / T
                F = np.eye(ns)
                if sf_on:
                    F[0, 2], F[1, 2] = vn * T, ve * T
                F[0, i_psi], F[1, i_psi] = -ve * T, vn * T
                F[i_psi, i_b] = T
                Q = np.zeros(ns)
                Q[0] = Q[1] = cfg.odo_noise ** 2 * T
                if sf_on:
                    Q[2] = cfg.sf_random_walk ** 2 * T
                Q[i_psi] = q_psi * T
                Q[i_b] = q_b * T
                P = F @ P @ F.T + np.diag(Q)
        # GPS fixes up to this epoch
        tk = t[a]
        while g_ptr < len(gt) and gt[g_ptr] <= tk + 0.5 * dt:
            gi = g_ptr
            g_ptr += 1
            if not use_gps[gi]:
                continue
            speed_now = float(np.mean(v_odo[max(0, a - step):a + 1]))
            fast = speed_now > cfg.cog_speed and gspeed[gi] > cfg.cog_speed
            fast_since = (fast_since if fast_since is not None else gt[gi]) if fast else None
            cog_ok = fast and gt[gi] - fast_since >= cfg.cog_time_s
            if psi is None:
                if cog_ok:  # course-over-ground initialisation
                    psi, t_heading = float(cog[gi]), float(gt[gi])
                    P[i_psi, i_psi] = np.radians(3.0) ** 2
                    P[i_psi, :i_psi] = P[:i_psi, i_psi] = 0.0
                lat, lon, h = float(glat[gi]), float(glon[gi]), float(gh[gi])  # held at the fix until then
                used[j] = True
                continue
            if cog_ok:
                gate = 3 * np.sqrt(P[i_psi, i_psi]) + np.radians(cfg.reset_gate_deg)
                if abs(_wrap(cog[gi] - psi)) > gate:  # non-linear reset (Fig. 2.14)
                    psi = float(cog[gi])
                    lat, lon, h = float(glat[gi]), float(glon[gi]), float(gh[gi])
                    P[i_psi, :] = P[:, i_psi] = 0.0
                    P[i_psi, i_psi] = np.radians(3.0) ** 2
                    P[:2, :] = P[:, :2] = 0.0
                    P[0, 0] = P[1, 1] = cfg.gps_sigma ** 2
                    resets.append(float(gt[gi]))
                    used[j] = True
                    continue
            rm, rn = radii(lat)
            z = np.array([(glat[gi] - lat) * (rm + gh[gi]), (glon[gi] - lon) * (rn + gh[gi]) * np.cos(lat)])
            H = np.zeros((2, ns))
            H[0, 0] = H[1, 1] = 1.0
            R = np.eye(2) * cfg.gps_sigma ** 2
            S = H @ P @ H.T + R
            if float(z @ np.linalg.solve(S, z)) > cfg.gate ** 2:  # inconsistent fix: not used
                rejected += 1
                if rejected >= 3:  # three in a row: the solution is off, restart the position at the fix
                    lat, lon, h = float(glat[gi]), float(glon[gi]), float(gh[gi])
                    P[:2, :] = P[:, :2] = 0.0
                    P[0, 0] = P[1, 1] = cfg.gps_sigma ** 2
                    rejected = 0
                    used[j] = True
                continue
            rejected = 0
            K = np.linalg.solve(S, H @ P).T
            dx = K @ z
            ikh = np.eye(ns) - K @ H
            P = ikh @ P @ ikh.T + K @ R @ K.T
            P = 0.5 * (P + P.T)
            # closed-loop reset (eq. 2.27)
            lat += dx[0] / (rm + h)
            lon += dx[1] / ((rn + h) * np.cos(lat))
            if sf_on:
                k_corr += dx[2]
            psi = float(psi + dx[i_psi])
            bias -= dx[i_b]
            used[j] = True
        out["t"][j], out["lat"][j], out["lon"][j], out["h"][j] = tk, lat, lon, h
        out["heading"][j] = np.nan if psi is None else _wrap(psi)
        out["pitch"][j], out["speed"][j] = pitch[a], v_odo[a] * (1 + k_corr)
        out["sf"][j] = 1.0 / (1.0 + k_corr) - 1.0 if sf_on else np.nan
        out["bias"][j] = bias
        sig[j, idx] = np.sqrt(np.diag(P))
    if psi is None:
        notes.append("the heading was never initialised: no GPS course over ground above "
                     f"{cfg.cog_speed:g} m/s for {cfg.cog_time_s:g} s")
    return LnsResult(out["t"], out["lat"], out["lon"], out["h"], out["heading"], out["pitch"], out["speed"],
                     out["sf"], out["bias"], sig, used, resets, t_heading, notes)


def track_length(lat: np.ndarray, lon: np.ndarray, min_step_m: float = 20.0) -> np.ndarray:
    """Cumulative path length (m) of a noisy position track (rad), counting a new point only once it is
    ``min_step_m`` from the last one counted (so position noise at rest adds nothing)."""
    rm, rn = radii(lat)
    y, x = lat * rm, lon * rn * np.cos(lat[0])
    out = np.zeros(len(lat))
    last, total = 0, 0.0
    for i in range(1, len(lat)):
        d = np.hypot(y[i] - y[last], x[i] - x[last])
        if d >= min_step_m:
            total += d
            last = i
        out[i] = total
    return out


def error_statistics(err_m: np.ndarray, distance_m: np.ndarray, skip_m: float) -> dict:
    """Thesis tables 2.3-2.9 statistics of the position error in % of the distance travelled.

    Samples with ``distance_m < skip_m`` are left out ("immediately after the GPS signal loss the
    travelled distance is zero and so the percentage error tends to infinite"). Returns
    ``max``, ``mean``, ``std``, ``rms`` and ``one_sigma`` (= mean + std, as the thesis' "Err 1σ") in
    %, ``distance_m`` the distance travelled, ``final_error_m``.
    """
    sel = distance_m >= skip_m
    if not sel.any():
        return {k: None for k in ("max", "mean", "std", "rms", "one_sigma")} | {
            "distance_m": float(distance_m[-1]) if len(distance_m) else 0.0, "final_error_m": None}
    pct = 100.0 * err_m[sel] / distance_m[sel]
    mean, std = float(np.mean(pct)), float(np.std(pct))
    return {"max": float(np.max(pct)), "mean": mean, "std": std, "rms": float(np.sqrt(np.mean(pct ** 2))),
            "one_sigma": mean + std, "distance_m": float(distance_m[-1]), "final_error_m": float(err_m[-1])}
