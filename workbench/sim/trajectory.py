"""True kinematics of a land vehicle on a road: legs -> position, velocity, attitude, rates, forces.

A road is a list of legs (:class:`Leg`): straights (optionally on a slope), constant-rate
turns and stops. At the start of each leg three channels move to the leg's targets — speed,
yaw rate and road slope (pitch) — each along a jerk-limited S-curve (:func:`s_curve`), so
acceleration and jerk stay within :class:`Limits`. A turn of ``angle`` at ``rate`` lasts
``angle / rate``: the S-curves into and out of it are point-symmetric, so the heading turns by
exactly ``angle`` once the next leg has brought the rate back.

Everything is evaluated on the sample grid from closed forms (channel values and their first
two derivatives); heading, position and geodetic coordinates are integrated with the
Euler-Maclaurin corrected trapezoid (``h/2 (y0 + y1) - h²/12 (y1' - y0')``, exact for cubics),
so the truth does not depend on an integration scheme a filter might share.

Frames: vehicle frame ``v`` (x forward along the road, y right, z down; roll 0, pitch = slope,
heading ψ); IMU body frame ``b`` = vehicle frame rotated by the boresight
``C_b^v`` (roll, pitch, yaw); the IMU sits at the lever arm ``l^v`` from the vehicle reference
point (the odometer's axle centre). NED navigation frame, WGS-84 (``workbench/earth.py``).
Rates and forces:

    ω_nv^v = [-ψ' sin θ, θ', ψ' cos θ]                           (Euler rates, roll 0)
    ω_iv^v = ω_nv^v + C_n^v (ω_ie^n + ω_en^n)                    (Earth rate + transport rate)
    f^n    = v̇^n - g^n + (ω_en^n + 2 ω_ie^n) x v^n               (Groves eq. 5.53 rearranged)
    f_imu^v = f_ref^v + ω̇_iv^v x l + ω_iv^v x (ω_iv^v x l),   ω_ib^b = C_v^b ω_iv^v,  f^b = C_v^b f_imu^v

(the local-level frames at the reference point and at the IMU differ by ``|l| / R`` ~ 1e-7 rad,
neglected; gravity is normal gravity at the reference point).

Public: :class:`Limits`, :class:`Leg`, :func:`leg_from_dict`, :func:`s_curve`,
:class:`Trajectory`, :func:`generate`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from workbench.earth import EARTH_RATE, normal_gravity, radii
from workbench.errors import WorkbenchError


@dataclass(frozen=True)
class Limits:
    """Acceleration and jerk limits of the three channels (SI).

    ``accel`` m/s², ``jerk`` m/s³ (speed); ``yaw_accel`` rad/s², ``yaw_jerk`` rad/s³ (yaw rate);
    ``pitch_rate`` rad/s, ``pitch_accel`` rad/s² (slope changes).
    """

    accel: float = 1.5
    jerk: float = 1.0
    yaw_accel: float = 0.1
    yaw_jerk: float = 0.2
    pitch_rate: float = 0.02
    pitch_accel: float = 0.02


@dataclass(frozen=True)
class Leg:
    """One leg of the road: ``duration_s`` at the targets ``speed`` m/s, ``yaw_rate`` rad/s
    (positive clockwise seen from above) and ``slope`` rad (positive uphill); ``kind`` and
    ``label`` describe it (``straight``, ``turn``, ``stop``)."""

    kind: str
    duration_s: float
    speed: float
    yaw_rate: float = 0.0
    slope: float = 0.0
    label: str = ""


def leg_from_dict(d: Mapping, where: str = "leg") -> Leg:
    """A leg from its lab-unit description.

    ``{kind: straight, duration_s | length_m, speed_mps, slope_deg}``;
    ``{kind: turn, angle_deg, rate_dps, speed_mps}`` (the sign of ``angle_deg`` gives the
    direction, positive = right/clockwise); ``{kind: stop, duration_s}``.
    """
    kind = d.get("kind")
    try:
        if kind == "straight":
            speed = float(d["speed_mps"])
            dur = float(d["duration_s"]) if "duration_s" in d else float(d["length_m"]) / speed
            return Leg("straight", dur, speed, 0.0, float(np.radians(d.get("slope_deg", 0.0))), d.get("label", ""))
        if kind == "turn":
            angle, rate = float(np.radians(d["angle_deg"])), abs(float(np.radians(d["rate_dps"])))
            if rate <= 0:
                raise WorkbenchError(f"{where}: rate_dps must be > 0")
            return Leg("turn", abs(angle) / rate, float(d["speed_mps"]), np.sign(angle) * rate,
                       float(np.radians(d.get("slope_deg", 0.0))), d.get("label", ""))
        if kind == "stop":
            return Leg("stop", float(d["duration_s"]), 0.0, 0.0, float(np.radians(d.get("slope_deg", 0.0))),
                       d.get("label", ""))
    except KeyError as exc:
        raise WorkbenchError(f"{where}: {kind} needs field {exc.args[0]!r}") from None
    except (TypeError, ValueError):
        raise WorkbenchError(f"{where}: a field is not a number") from None
    raise WorkbenchError(f"{where}: unknown kind {kind!r} (straight, turn or stop)")


def s_curve(delta: float, rate_max: float, accel_max: float, tau: np.ndarray) -> tuple:
    """Jerk-limited transition by ``delta``: value, first and second derivative at ``tau`` s.

    The first derivative is limited to ``rate_max`` and the second to ``accel_max`` (for the
    speed channel: acceleration and jerk). Phases: second derivative ``+accel_max`` for
    ``t_j = r / accel_max``, then 0 for ``t_a`` at the peak rate ``r = min(rate_max,
    sqrt(|delta| accel_max))``, then ``-accel_max`` for ``t_j``. Returns ``(value, d1, d2, duration)``
    with duration ``2 t_j + t_a``; before 0 the value is 0, after the duration ``delta``.
    """
    tau = np.asarray(tau, float)
    d = abs(delta)
    if d == 0.0:
        z = np.zeros_like(tau)
        return z, z, z, 0.0
    j = accel_max
    r = min(rate_max, np.sqrt(d * j))
    tj = r / j
    ta = d / r - tj
    total = 2 * tj + ta
    x = np.clip(tau, 0.0, total)
    w = total - x
    rise, fall = x < tj, w < tj
    v = np.where(rise, 0.5 * j * x ** 2, np.where(fall, d - 0.5 * j * w ** 2, 0.5 * r * tj + r * (x - tj)))
    d1 = np.where(rise, j * x, np.where(fall, j * w, r))
    d2 = np.where(rise, j, np.where(fall, -j, 0.0))
    d1 = np.where(tau >= total, 0.0, np.where(tau <= 0, 0.0, d1))
    d2 = np.where((tau >= total) | (tau < 0), 0.0, d2)
    s = np.sign(delta)
    return s * v, s * d1, s * d2, total


def _channel(legs: Sequence[Leg], attr: str, t: np.ndarray, starts: np.ndarray, rate_max: float,
             accel_max: float, initial: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One channel (value, d1, d2) over ``t``: S-curves at each leg start to the leg's target."""
    val = np.full_like(t, initial)
    d1 = np.zeros_like(t)
    d2 = np.zeros_like(t)
    prev = initial
    for k, leg in enumerate(legs):
        target = getattr(leg, attr)
        if target != prev:
            sel = t >= starts[k]
            v, a, b, total = s_curve(target - prev, rate_max, accel_max, t[sel] - starts[k])
            if total > leg.duration_s + 1e-9:
                raise WorkbenchError(f"road leg {k} ({leg.kind} {leg.label}): {leg.duration_s:.1f} s is shorter than "
                                     f"the {total:.1f} s the {attr} change needs within the limits")
            val[sel] += v
            d1[sel] += a
            d2[sel] += b
            prev = target
    return val, d1, d2


def _cumtrapz_em(y: np.ndarray, dy: np.ndarray, h: float) -> np.ndarray:
    """Cumulative integral from 0 with the Euler-Maclaurin corrected trapezoid (exact for cubics)."""
    inc = 0.5 * h * (y[1:] + y[:-1]) - h * h / 12.0 * (dy[1:] - dy[:-1])
    return np.concatenate([np.zeros((1,) + y.shape[1:]), np.cumsum(inc, axis=0)])


def _skew_rows(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices (N, 3, 3) of the rows of ``v`` (N, 3)."""
    k = np.zeros(v.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    k[..., 1, 0], k[..., 2, 0], k[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return k


def _rot_vn(theta: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """C_v^n (N, 3, 3) for roll 0, pitch ``theta``, heading ``psi``: Rz(ψ) Ry(θ)."""
    ct, st, cp, sp = np.cos(theta), np.sin(theta), np.cos(psi), np.sin(psi)
    c = np.zeros(theta.shape + (3, 3))
    c[..., 0, 0], c[..., 0, 1], c[..., 0, 2] = cp * ct, -sp, cp * st
    c[..., 1, 0], c[..., 1, 1], c[..., 1, 2] = sp * ct, cp, sp * st
    c[..., 2, 0], c[..., 2, 1], c[..., 2, 2] = -st, 0.0, ct
    return c


@dataclass(frozen=True)
class Trajectory:
    """True motion at the sample times ``t`` (N,) s.

    IMU point: ``lat``, ``lon`` rad, ``h`` m (geodetic, WGS-84); ``v_ned`` (N, 3) m/s;
    ``c_bn`` (N, 3, 3) body-to-NED; ``omega_ib_b`` (N, 3) rad/s; ``f_b`` (N, 3) m/s²
    (specific force). Vehicle reference point: ``ref_lat``, ``ref_lon``, ``ref_h``, ``speed``
    (N,) m/s along the road, ``distance`` (N,) m travelled, ``heading``, ``pitch`` (N,) rad of the
    vehicle frame. ``leg`` (N,) index of the leg each sample belongs to.
    """

    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    v_ned: np.ndarray
    c_bn: np.ndarray
    omega_ib_b: np.ndarray
    f_b: np.ndarray
    ref_lat: np.ndarray
    ref_lon: np.ndarray
    ref_h: np.ndarray
    ref_v_ned: np.ndarray
    speed: np.ndarray
    distance: np.ndarray
    heading: np.ndarray
    pitch: np.ndarray
    leg: np.ndarray
    leg_starts: np.ndarray


def generate(legs: Sequence[Leg], sample_rate_hz: float, lat0: float, lon0: float, h0: float,
             heading0: float = 0.0, limits: Limits = Limits(), lever_arm=(0.0, 0.0, 0.0),
             boresight=(0.0, 0.0, 0.0)) -> Trajectory:
    """The true trajectory of ``legs`` from (``lat0``, ``lon0`` rad, ``h0`` m) heading ``heading0`` rad.

    ``lever_arm`` (3,) m: IMU position from the vehicle reference point, vehicle frame;
    ``boresight`` (3,) rad: roll, pitch, yaw of the IMU body w.r.t. the vehicle (ZYX).
    The vehicle starts at rest on a level road.
    """
    from scipy.spatial.transform import Rotation

    if not legs:
        raise WorkbenchError("road: no legs")
    durations = np.array([leg.duration_s for leg in legs])
    if np.any(durations <= 0):
        raise WorkbenchError(f"road leg {int(np.argmax(durations <= 0))}: duration must be > 0")
    starts = np.concatenate([[0.0], np.cumsum(durations)])
    dt = 1.0 / sample_rate_hz
    n = int(round(starts[-1] * sample_rate_hz))
    t = np.arange(n) * dt
    v, vd1, _ = _channel(legs, "speed", t, starts, limits.accel, limits.jerk, 0.0)
    r, rd1, rd2 = _channel(legs, "yaw_rate", t, starts, limits.yaw_accel, limits.yaw_jerk, 0.0)
    th, thd1, thd2 = _channel(legs, "slope", t, starts, limits.pitch_rate, limits.pitch_accel, 0.0)
    v = np.maximum(v, 0.0)
    psi = heading0 + _cumtrapz_em(r, rd1, dt)
    ct, st, cp, sp = np.cos(th), np.sin(th), np.cos(psi), np.sin(psi)
    u = np.stack([ct * cp, ct * sp, -st], axis=1)  # road direction in NED
    du = np.stack([-st * thd1 * cp - ct * sp * r, -st * thd1 * sp + ct * cp * r, -ct * thd1], axis=1)
    vn = v[:, None] * u
    an = vd1[:, None] * u + v[:, None] * du  # nav-frame derivative of v^n
    distance = _cumtrapz_em(v, vd1, dt)
    # geodetic coordinates of the reference point (two passes: the radii depend on latitude)
    h = h0 - _cumtrapz_em(vn[:, 2], an[:, 2], dt)
    lat = np.full(n, lat0)
    for _ in range(2):
        rm, rn = radii(lat)
        lat = lat0 + _cumtrapz_em(vn[:, 0] / (rm + h), an[:, 0] / (rm + h), dt)
    rm, rn = radii(lat)
    rate_e = vn[:, 1] / ((rn + h) * np.cos(lat))
    lon = lon0 + _cumtrapz_em(rate_e, an[:, 1] / ((rn + h) * np.cos(lat)), dt)
    # rates: Earth, transport, Euler
    w_ie = EARTH_RATE * np.stack([np.cos(lat), np.zeros(n), -np.sin(lat)], axis=1)
    w_en = np.stack([vn[:, 1] / (rn + h), -vn[:, 0] / (rm + h), -vn[:, 1] * np.tan(lat) / (rn + h)], axis=1)
    g = normal_gravity(lat, h)
    f_n = an - np.stack([np.zeros(n), np.zeros(n), g], axis=1) + np.cross(w_en + 2 * w_ie, vn)
    c_vn = _rot_vn(th, psi)
    c_nv = np.swapaxes(c_vn, 1, 2)
    w_nv = np.stack([-r * st, thd1, r * ct], axis=1)
    w_in_v = np.einsum("nij,nj->ni", c_nv, w_ie + w_en)
    w_iv = w_nv + w_in_v
    f_v = np.einsum("nij,nj->ni", c_nv, f_n)
    lever = np.asarray(lever_arm, float)
    c_bv = Rotation.from_euler("ZYX", [boresight[2], boresight[1], boresight[0]]).as_matrix()
    if np.any(lever != 0):
        w_nv_dot = np.stack([-rd1 * st - r * thd1 * ct, thd2, rd1 * ct - r * thd1 * st], axis=1)
        w_iv_dot = w_nv_dot - np.cross(w_nv, w_in_v)
        f_v = f_v + np.cross(w_iv_dot, lever) + np.cross(w_iv, np.cross(w_iv, lever))
        w_ev = w_nv + np.einsum("nij,nj->ni", c_nv, w_en)
        dv = np.einsum("nij,nj->ni", c_vn, np.cross(w_ev, lever))
        dp = np.einsum("nij,j->ni", c_vn, lever)
    else:
        dv = dp = np.zeros((n, 3))
    # the IMU's own local-level frame n' is the reference point's turned by rho (the transport
    # rotation over the offset dp): x^n' = x^n - rho x x^n; gravity there is g(imu) along its down
    dlat, dlon = dp[:, 0] / (rm + h), dp[:, 1] / ((rn + h) * np.cos(lat))
    rho = np.stack([dlon * np.cos(lat), -dlat, -dlon * np.sin(lat)], axis=1)
    g_imu = normal_gravity(lat + dlat, h - dp[:, 2])
    down = np.array([0.0, 0.0, 1.0])
    dg_n = g_imu[:, None] * (down + np.cross(rho, down)) - g[:, None] * down  # g(imu) - g(ref), NED of ref
    f_v = f_v - np.einsum("nij,nj->ni", c_nv, dg_n)
    c_vb = c_bv.T
    omega_b = w_iv @ c_vb.T
    f_b = f_v @ c_vb.T
    c_nn = np.eye(3) - _skew_rows(rho)  # C_n^n' (first order)
    c_bn = c_nn @ c_vn @ c_bv
    v_imu = np.einsum("nij,nj->ni", c_nn, vn + dv)
    leg_idx = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(legs) - 1)
    return Trajectory(t=t, lat=lat + dp[:, 0] / (rm + h), lon=lon + dp[:, 1] / ((rn + h) * np.cos(lat)),
                      h=h - dp[:, 2], v_ned=v_imu, c_bn=c_bn, omega_ib_b=omega_b, f_b=f_b,
                      ref_lat=lat, ref_lon=lon, ref_h=h, ref_v_ned=vn, speed=v, distance=distance,
                      heading=psi, pitch=th, leg=leg_idx, leg_starts=starts)
