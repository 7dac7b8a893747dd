"""Closed-form synthetic IMU data for the filter tests (no simulator involved).

A unit on a level, Earth-fixed table at latitude 40.8°: the true body rate is
``C^T (w_ie + table_rate * down)``, the specific force ``C^T (0, 0, -g)``, the field
``C^T m_n``; constant biases and seeded white noise of the given densities are added.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from workbench.earth import earth_rate_ned, gravity_ned
from workbench.nav.compensate import ImuSamples, ProcessNoise

LAT = np.radians(40.8)
FS = 100.0
ARW = np.radians(0.2) / 60.0  # rad/sqrt(s): 0.2 deg/sqrt(h), industrial MEMS (thesis table 1.1)
VRW = 0.05 / 60.0  # m/s/sqrt(s): 0.05 m/s/sqrt(h) (thesis table 1.2)
MAG_NED = 48.0 * np.array([np.cos(np.radians(60.0)), 0.0, np.sin(np.radians(60.0))])  # µT, dip 60°
NOISE = ProcessNoise(np.full(3, ARW), np.full(3, VRW), np.full(3, 1e-8), np.full(3, 1e-7))


def table_run(mount: Rotation, duration_s: float, seed: int, gyro_bias=np.zeros(3), accel_bias=np.zeros(3),
              rate_profile=None, mag_bias=np.zeros(3), mag_noise_ut: float = 0.05, arw: float = ARW, vrw: float = VRW):
    """(ImuSamples, true attitudes Rotation (N,)) of a table run; ``rate_profile(t)`` rad/s about down;
    ``arw`` rad/√s and ``vrw`` m/s/√s the white noise densities (default the module's)."""
    rng = np.random.default_rng(seed)
    n = int(round(duration_s * FS))
    t = np.arange(n) / FS
    rate = np.zeros(n) if rate_profile is None else rate_profile(t)
    psi = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1])) / FS])
    att = Rotation.from_euler("z", psi[:, None]) * mount
    w_n = earth_rate_ned(LAT) + np.outer(rate, [0.0, 0.0, 1.0])
    gyro = att.inv().apply(w_n) + gyro_bias + rng.normal(0.0, arw * np.sqrt(FS), (n, 3))
    accel = (att.inv().apply(np.tile(-gravity_ned(LAT), (n, 1))) + accel_bias
             + rng.normal(0.0, vrw * np.sqrt(FS), (n, 3)))
    mag = att.inv().apply(np.tile(MAG_NED, (n, 1))) + mag_bias + rng.normal(0.0, mag_noise_ut, (n, 3))
    return ImuSamples(t, gyro, accel, mag, None, 1.0 / FS, (), "synthetic"), att
