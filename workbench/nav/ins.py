"""Strapdown INS mechanisation in the local-level NED frame (WGS-84), compiled with numba.

State: geodetic latitude, longitude (rad), height (m), velocity w.r.t. the Earth in NED
(m/s), body-to-NED attitude ``C_b^n``. Per sample interval ``dt`` (instantaneous samples
``k`` and ``k+1`` of the body rate w.r.t. inertial space and of the specific force):

    C(k+1) = Exp(-ω_in^n dt) C(k) Exp((ω_k + ω_k+1) dt / 2)        attitude (body increment, frame rotation)
    v(k+1) = v(k) + [ (C(k) f_k + C(k+1) f_k+1) / 2 + g^n - (2 ω_ie^n + ω_en^n) x v ] dt
    φ, λ, h from the trapezoid of v_N / (R_M + h), v_E / ((R_N + h) cos φ), -v_D

(Groves, Principles of GNSS, Inertial and Multisensor Navigation, eq. 5.46-5.56; paper 001
(shared/seeds/001_...) sec. 2 uses the same mechanisation). The scheme is second order in
``dt``; its error on a simulated drive is measured in ``tests/nav/test_ins.py``.

Public: :func:`radii`, :func:`expm_so3`, :func:`mechanise`, :class:`NavState`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from workbench.earth import EARTH_RATE, GAMMA_E, GAMMA_P, WGS84_A, WGS84_B, WGS84_E2, WGS84_F, GM

_K = (WGS84_B * GAMMA_P) / (WGS84_A * GAMMA_E) - 1.0
_M = EARTH_RATE ** 2 * WGS84_A ** 2 * WGS84_B / GM


@numba.njit(cache=True)
def radii(lat: float) -> tuple[float, float]:
    """Meridian and normal radii of curvature (m) at geodetic latitude ``lat`` rad (WGS-84)."""
    s2 = np.sin(lat) ** 2
    rn = WGS84_A / np.sqrt(1.0 - WGS84_E2 * s2)
    return rn * (1.0 - WGS84_E2) / (1.0 - WGS84_E2 * s2), rn


@numba.njit(cache=True)
def _gravity(lat: float, h: float) -> float:
    """Normal gravity, m/s² (Somigliana + free-air correction, as workbench.earth.normal_gravity)."""
    s2 = np.sin(lat) ** 2
    g0 = GAMMA_E * (1.0 + _K * s2) / np.sqrt(1.0 - WGS84_E2 * s2)
    return g0 * (1.0 - 2.0 / WGS84_A * (1.0 + WGS84_F + _M - 2.0 * WGS84_F * s2) * h + 3.0 / WGS84_A ** 2 * h * h)


@numba.njit(cache=True)
def expm_so3(a0: float, a1: float, a2: float) -> np.ndarray:
    """Rotation matrix ``Exp([a×])`` (3, 3) of the rotation vector ``a`` rad (Rodrigues)."""
    th2 = a0 * a0 + a1 * a1 + a2 * a2
    th = np.sqrt(th2)
    if th < 1e-8:
        s, c = 1.0 - th2 / 6.0, 0.5 - th2 / 24.0
    else:
        s, c = np.sin(th) / th, (1.0 - np.cos(th)) / th2
    k = np.array([[0.0, -a2, a1], [a2, 0.0, -a0], [-a1, a0, 0.0]])
    return np.eye(3) + s * k + c * (k @ k)


@numba.njit(cache=True)
def _transport(lat: float, h: float, vn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Earth rate and transport rate in NED (rad/s) at (lat, h) and velocity ``vn``."""
    rm, rn = radii(lat)
    w_ie = np.array([EARTH_RATE * np.cos(lat), 0.0, -EARTH_RATE * np.sin(lat)])
    w_en = np.array([vn[1] / (rn + h), -vn[0] / (rm + h), -vn[1] * np.tan(lat) / (rn + h)])
    return w_ie, w_en


@numba.njit(cache=True)
def _step(lat, lon, h, v, c, w0, w1, f0, f1, dt):
    """One mechanisation interval; returns the new (lat, lon, h, v, C)."""
    w_ie, w_en = _transport(lat, h, v)
    w_in = w_ie + w_en
    cb = c @ expm_so3(0.5 * (w0[0] + w1[0]) * dt, 0.5 * (w0[1] + w1[1]) * dt, 0.5 * (w0[2] + w1[2]) * dt)
    c_new = expm_so3(-w_in[0] * dt, -w_in[1] * dt, -w_in[2] * dt) @ cb
    fn = 0.5 * (c @ f0 + c_new @ f1)
    g = _gravity(lat, h)
    cor = 2.0 * w_ie + w_en
    acc = fn - np.cross(cor, v)
    acc[2] += g
    v_pred = v + acc * dt
    acc2 = fn - np.cross(cor, 0.5 * (v + v_pred))
    acc2[2] += g
    v_new = v + acc2 * dt
    rm, rn = radii(lat)
    vm = 0.5 * (v + v_new)
    h_new = h - vm[2] * dt
    hm = 0.5 * (h + h_new)
    lat_new = lat + vm[0] / (rm + hm) * dt
    lon_new = lon + vm[1] / ((rn + hm) * np.cos(0.5 * (lat + lat_new))) * dt
    return lat_new, lon_new, h_new, v_new, c_new


@numba.njit(cache=True)
def _run(lat, lon, h, v, c, gyro, accel, dt, out_pos, out_v, out_c):
    n = gyro.shape[0]
    out_pos[0, 0], out_pos[0, 1], out_pos[0, 2] = lat, lon, h
    out_v[0] = v
    out_c[0] = c
    for k in range(n - 1):
        lat, lon, h, v, c = _step(lat, lon, h, v, c, gyro[k], gyro[k + 1], accel[k], accel[k + 1], dt)
        out_pos[k + 1, 0], out_pos[k + 1, 1], out_pos[k + 1, 2] = lat, lon, h
        out_v[k + 1] = v
        out_c[k + 1] = c


@dataclass(frozen=True)
class NavState:
    """Mechanised solution at each sample: ``lat``, ``lon`` rad, ``h`` m (N,), ``v_ned`` (N, 3) m/s,
    ``c_bn`` (N, 3, 3) body-to-NED."""

    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    v_ned: np.ndarray
    c_bn: np.ndarray


def mechanise(lat: float, lon: float, h: float, v_ned: np.ndarray, c_bn: np.ndarray, gyro: np.ndarray,
              accel: np.ndarray, dt: float) -> NavState:
    """Free-inertial solution from the initial state at sample 0 over the samples ``gyro`` (N, 3)
    rad/s and ``accel`` (N, 3) m/s² (body frame, instantaneous samples at interval ``dt`` s)."""
    n = len(gyro)
    pos, vel, att = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3, 3))
    _run(float(lat), float(lon), float(h), np.asarray(v_ned, float).copy(), np.asarray(c_bn, float).copy(),
         np.ascontiguousarray(gyro, dtype=float), np.ascontiguousarray(accel, dtype=float), float(dt), pos, vel, att)
    return NavState(pos[:, 0], pos[:, 1], pos[:, 2], vel, att)
