"""A unit turned by hand: still holds and free tumbles, with the truth of every instant.

The motion alternates still holds (``still_s``) and moves (``move_s``); each move turns the
unit about a random body axis by a random angle (``turn_deg`` range) with the rate profile
``w(t) = axis * theta * (2 / T) sin^2(pi t / T)`` (zero rate and acceleration at both ends), so
the attitude has a closed form: ``C_nb(t) = C_nb(t0) Rot(axis, theta * s(t))`` with
``s(t) = t / T - sin(2 pi t / T) / (2 pi)``. The hand turns the unit about a point ``lever_m``
away from it (body frame), which adds ``dw/dt x r + w x (w x r)`` to the specific force while
it moves; the position is otherwise fixed. ``still_s = 0`` gives one continuous tumble.

True inputs (body frame, SI): rate ``w_b + C_bn w_ie^n``, specific force ``-C_bn g^n`` plus the
lever-arm term, field ``C_bn h^n``; :class:`workbench.sim.sensor.VirtualIMU` turns them into
samples. The result is an in-memory session whose whole record is one ``free`` step.

Public: :class:`HandheldTruth`, :func:`handheld_session`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from workbench.earth import earth_rate_ned, gravity_ned
from workbench.grades import UnitTruth
from workbench.session import Session, Site, StepRecord
from workbench.sim.sensor import VirtualIMU
from workbench.values import Unit


@dataclass(frozen=True)
class HandheldTruth:
    """What the hand did: ``attitude`` (N,) body-to-NED, ``still`` (N,) bool (no motion at all),
    ``field_ned`` (3,) µT, the unit's true models in ``unit``."""

    attitude: Rotation
    still: np.ndarray
    field_ned: np.ndarray
    unit: UnitTruth


def _field(norm_ut: float, dip_deg: float, decl_deg: float) -> np.ndarray:
    dip, dec = np.radians(dip_deg), np.radians(decl_deg)
    return norm_ut * np.array([np.cos(dip) * np.cos(dec), np.cos(dip) * np.sin(dec), np.sin(dip)])


def handheld_session(truth: UnitTruth, seed: int, duration_s: float = 120.0, still_s: float = 3.0,
                     move_s: float = 2.0, turn_deg: tuple[float, float] = (40.0, 140.0),
                     lever_m: tuple[float, float, float] = (0.05, 0.0, 0.0), field_ut: float = 48.0,
                     dip_deg: float = 60.0, declination_deg: float = 2.0, latitude_deg: float = 48.0,
                     temperature_c: float = 23.0) -> tuple[Session, HandheldTruth]:
    """Simulate ``duration_s`` of hand-held motion (see the module docstring); returns (session, truth).

    ``seed`` drives both the motion and the sensor noise. Angles in degrees, lever arm in m
    (body frame), field norm µT, temperature °C (constant).
    """
    fs = truth.sample_rate_hz
    n = int(round(duration_s * fs))
    t = np.arange(n) / fs
    rng_motion, rng_noise = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[0]), \
        int(np.random.SeedSequence(seed).spawn(2)[1].generate_state(1)[0])
    rotvec = np.zeros((n, 3))  # body rotation since the segment start, applied to the segment's start attitude
    rate = np.zeros((n, 3))
    rate_dot = np.zeros((n, 3))
    still = np.ones(n, bool)
    seg_start = np.zeros(n, int)
    starts: list[Rotation] = [Rotation.from_euler("z", rng_motion.uniform(0, 360), degrees=True)]
    k = int(round(still_s * fs))
    m = max(2, int(round(move_s * fs)))
    while k < n:
        axis = rng_motion.normal(size=3)
        axis /= np.linalg.norm(axis)
        theta = np.radians(rng_motion.uniform(*turn_deg)) * rng_motion.choice([-1.0, 1.0])
        idx = np.arange(k, min(n, k + m))
        tau = (idx - k) / fs
        big_t = m / fs
        s = tau / big_t - np.sin(2 * np.pi * tau / big_t) / (2 * np.pi)
        rotvec[idx] = np.outer(theta * s, axis)
        rate[idx] = np.outer(theta * 2 / big_t * np.sin(np.pi * tau / big_t) ** 2, axis)
        rate_dot[idx] = np.outer(theta * 2 / big_t * np.pi / big_t * np.sin(2 * np.pi * tau / big_t), axis)
        still[idx] = False
        seg_start[idx] = len(starts) - 1
        after = idx[-1] + 1
        end = starts[-1] * Rotation.from_rotvec(theta * axis)
        starts.append(end)
        hold = np.arange(after, min(n, after + int(round(still_s * fs))))
        seg_start[hold] = len(starts) - 1
        k = after + len(hold)
    start_rot = Rotation.concatenate(starts)[seg_start]
    att = start_rot * Rotation.from_rotvec(rotvec)  # body -> NED
    lat = np.radians(latitude_deg)
    lever = np.asarray(lever_m, float)
    f_b = att.inv().apply(-gravity_ned(lat)) + np.cross(rate_dot, lever) + np.cross(rate, np.cross(rate, lever))
    omega_b = rate + att.inv().apply(earth_rate_ned(lat))
    field = _field(field_ut, dip_deg, declination_deg)
    m_b = att.inv().apply(field) if truth.mag is not None else None
    out = VirtualIMU(truth, rng_noise).measure(omega_b, f_b, m_b, np.full(n, temperature_c))
    data = {"t": t, "step": np.zeros(n, int)}
    for name, cols in (("gyro", "gx gy gz"), ("accel", "ax ay az"), ("mag", "mx my mz")):
        if out.get(name) is not None:
            data.update({c: out[name][:, i] for i, c in enumerate(cols.split())})
    data["temp"] = out["temp"]
    step = StepRecord(0, "free", 0.0, float(t[-1]), label="by hand")
    session = Session(id=f"handheld-{seed}", unit=Unit(truth.serial, truth.model),
                      site=Site(latitude_deg, field_norm_ut=None), sample_rate_hz=fs, procedure="magnetometer",
                      steps=[step], samples=pd.DataFrame(data))
    return session, HandheldTruth(att, still, field, truth)
