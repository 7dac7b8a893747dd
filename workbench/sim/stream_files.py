"""A hand-held recording written as another lab's logger writes it: four CSV streams with host
arrival stamps, a magnetometer on its own clock read faster than it updates, a recorder pause,
a saturating gyro; and the truth of every row.

The motion and the IMU samples are :func:`workbench.sim.handheld.handheld_session` (100 Hz on
the IMU's clock). The host clock runs ``host_ppm`` off the IMU's. The magnetometer updates at
``mag_update_hz`` on its own clock (``mag_ppm`` off) and is read by the host at ``mag_read_hz``:
a read before the next update returns the previous value again (a repeat). Its values are the
unit's magnetometer model (``TriadModel.apply``) on the true field at the update instants, white
noise and the output LSB. A pause of ``pause_s`` at ``pause_at_s`` drops every stream's samples
(the recorder stopped). Stamps come from :func:`workbench.sim.arrival.arrival_stamps` (bursts
40-250 ms apart). Files (as ``shared/data/marg_mpu6050_hmc5883l``): ``accelerometer.csv``
(g), ``gyroscope.csv`` (deg/s), ``temperature.csv`` (degC), ``magnetometer.csv`` (gauss).

Public: :func:`write_stream_recording` -> :class:`StreamTruth`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from workbench.grades import UnitTruth
from workbench.sim.arrival import arrival_stamps
from workbench.sim.handheld import HandheldTruth, handheld_session

G = 9.80665  # m/s^2 per g (the files' unit)
GAUSS_LSB = 1.0 / 1090.0  # gauss per count of the HMC5883L at its default gain


@dataclass(frozen=True)
class StreamTruth:
    """Truth of a written recording. Times on the host clock (s). ``imu_instants`` (N,) the true
    sampling instants of the IMU rows as written; ``mag_read_instants`` (M,) of the magnetometer
    rows; ``mag_repeated`` (M,) bool the read repeats the previous update; ``gyro_saturated`` (N,)
    bool a gyro value is at the range; ``host_to_motion(t)`` maps host time to the motion's time
    (``motion.attitude`` is sampled at ``k / imu_rate_hz`` of it); ``unit`` the unit's true models."""

    imu_instants: np.ndarray
    mag_read_instants: np.ndarray
    mag_repeated: np.ndarray
    gyro_saturated: np.ndarray
    motion: HandheldTruth
    unit: UnitTruth
    host_offset_s: float
    host_ppm: float
    temperature_c: float
    imu_rate_hz: float

    def host_to_motion(self, t: np.ndarray) -> np.ndarray:
        """Motion time (s) of host-clock instants ``t`` (s)."""
        return (np.asarray(t, float) - self.host_offset_s) / (1 + self.host_ppm * 1e-6)

    def true_mag(self, t_host: np.ndarray) -> np.ndarray:
        """Noise-free magnetometer output (N, 3) µT, body frame, at host instants ``t_host`` (attitude by slerp)."""
        u = self.host_to_motion(t_host)
        times = np.arange(len(self.motion.attitude)) / self.imu_rate_hz
        att = Slerp(times, self.motion.attitude)(np.clip(u, times[0], times[-1]))
        return self.unit.mag.apply(att.inv().apply(self.motion.field_ned), None, self.temperature_c)


def _write(path: Path, header: str, t: np.ndarray, values: np.ndarray) -> None:
    body = np.column_stack([t, values])
    np.savetxt(path, body, delimiter=",", header=header, comments="", fmt="%.17g")


def write_stream_recording(folder: str | Path, unit: UnitTruth, seed: int, duration_s: float = 60.0,
                           gyro_range_dps: float = 250.0, move_s: float = 0.8, host_ppm: float = 80.0,
                           mag_update_hz: float = 75.0, mag_read_hz: float = 77.0, mag_ppm: float = -120.0,
                           pause_at_s: float = 30.0, pause_s: float = 1.0, temperature_c: float = 25.0
                           ) -> StreamTruth:
    """Write the four stream files into ``folder`` (created) and return the truth (module docstring)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    unit = dataclasses.replace(unit, gyro_range=np.radians(gyro_range_dps))
    session, motion = handheld_session(unit, seed, duration_s=duration_s, still_s=2.0, move_s=move_s,
                                       temperature_c=temperature_c)
    fs = unit.sample_rate_hz
    host_offset = 2.0
    u = np.arange(len(session.samples)) / fs
    keep = ~((u >= pause_at_s) & (u < pause_at_s + pause_s))
    t_imu = host_offset + u[keep] * (1 + host_ppm * 1e-6)
    s = session.samples[keep]
    gyro = s[["gx", "gy", "gz"]].to_numpy()
    saturated = np.any(np.abs(gyro) >= unit.gyro_range * (1 - 1e-12), axis=1)
    stamps = arrival_stamps(t_imu, seed)
    _write(folder / "accelerometer.csv", "t_s,ax_g,ay_g,az_g", stamps, s[["ax", "ay", "az"]].to_numpy() / G)
    _write(folder / "gyroscope.csv", "t_s,gx_dps,gy_dps,gz_dps", stamps, np.degrees(gyro))
    _write(folder / "temperature.csv", "t_s,temp_c", stamps, s[["temp"]].to_numpy())
    # magnetometer: updates on its own clock, reads by the host
    rng = np.random.default_rng([seed, 75])
    upd = 0.004 + np.arange(int(duration_s * mag_update_hz)) / mag_update_hz * (1 + mag_ppm * 1e-6)
    reads = 0.0061 + np.arange(int(duration_s * mag_read_hz) - 2) / mag_read_hz
    reads = reads[(reads >= upd[0]) & (reads < upd[-1])]
    which = np.searchsorted(upd, reads, side="right") - 1  # the latest update at each read
    truth = StreamTruth(t_imu, np.zeros(0), np.zeros(0, bool), saturated, motion, unit, host_offset, host_ppm,
                        temperature_c, fs)
    white = unit.mag_noise.white * np.sqrt(mag_update_hz)  # µT per sample
    values = truth.true_mag(host_offset + upd * (1 + host_ppm * 1e-6)) + white * rng.standard_normal((len(upd), 3))
    counts = np.round(values / 100.0 / GAUSS_LSB)  # µT -> gauss -> counts
    mag_keep = ~((reads >= pause_at_s) & (reads < pause_at_s + pause_s))
    reads, which = reads[mag_keep], which[mag_keep]
    repeated = np.r_[False, which[1:] == which[:-1]]
    t_mag = host_offset + reads * (1 + host_ppm * 1e-6)
    _write(folder / "magnetometer.csv", "t_s,mx_gauss,my_gauss,mz_gauss", arrival_stamps(t_mag, seed + 1),
           counts[which] * GAUSS_LSB)
    return dataclasses.replace(truth, mag_read_instants=t_mag, mag_repeated=repeated)
