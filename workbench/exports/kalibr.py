"""Kalibr ``imu.yaml``: the white-noise densities and random walks of the ``noise`` block.

Kalibr's continuous-time units are the set's SI units: ``gyroscope_noise_density`` rad/s/√Hz
(= ARW N), ``gyroscope_random_walk`` rad/s²/√Hz (= RRW K), ``accelerometer_noise_density``
m/s²/√Hz (= VRW N), ``accelerometer_random_walk`` m/s³/√Hz (= K). Kalibr takes one value per
sensor: the largest axis is written (conservative). A random walk the record did not observe
is written as its 95 % upper bound; bias instability, quantization and rate ramp have no
Kalibr field. All of these are listed in ``dropped``.
"""

from __future__ import annotations

import numpy as np

from workbench.calset import CalibrationSet
from workbench.errors import ExportError
from workbench.registry import Export

FORMAT = "kalibr"
SUFFIX = ".yaml"
DESCRIPTION = "Kalibr imu.yaml noise parameters (continuous-time)"
DEFAULT_RATE_HZ = 100.0
FIELDS = {("gyro", "arw"): ("gyroscope_noise_density", "rad/s/sqrt(Hz)"),
          ("gyro", "rrw"): ("gyroscope_random_walk", "rad/s^2/sqrt(Hz)"),
          ("accel", "vrw"): ("accelerometer_noise_density", "m/s^2/sqrt(Hz)"),
          ("accel", "rrw"): ("accelerometer_random_walk", "m/s^3/sqrt(Hz)")}


def _value(calset: CalibrationSet, triad: str, term: str, dropped: list[str]) -> float:
    values = calset.noise_term(triad, term)
    if np.all(np.isfinite(values)):
        if np.ptp(values) > 0:
            dropped.append(f"noise.{triad}.{term}: per-axis values, the largest axis written")
        return float(values.max())
    bounds = [b[1] for b in (calset.noise.get(triad, {}).get(term + "_ci95") or []) if b is not None]
    if not bounds:
        raise ExportError(f"set {calset.id}: noise.{triad}.{term} is neither observed nor bounded; "
                          "Kalibr needs it (run the allan procedure)")
    dropped.append(f"noise.{triad}.{term}: not observed on some axis; the 95 % upper bound written")
    return float(max(np.nanmax(np.where(np.isfinite(values), values, 0.0)), max(bounds)))


def export(calset: CalibrationSet) -> Export:
    """``imu.yaml`` text for Kalibr; raises when the set has no gyro/accel noise terms."""
    if not calset.noise:
        raise ExportError(f"set {calset.id}: no noise block (run the allan procedure first)")
    dropped: list[str] = []
    lines = [f"# Kalibr IMU noise model of unit {calset.unit.serial} (calibration set {calset.id})",
             "rostopic: /imu0"]
    rate = (calset.notes.get("allan") or {}).get("sample_rate_hz")
    if rate is None:
        dropped.append(f"update_rate: not in the set; {DEFAULT_RATE_HZ:g} Hz written")
    lines.append(f"update_rate: {float(rate or DEFAULT_RATE_HZ):.6g}  # Hz")
    for (triad, term), (key, unit) in FIELDS.items():
        if triad not in calset.noise:
            raise ExportError(f"set {calset.id}: no noise.{triad} block; Kalibr needs {key}")
        lines.append(f"{key}: {_value(calset, triad, term, dropped):.6e}  # {unit}")
    for triad, block in calset.noise.items():
        for term, values in block.items():
            if not term.endswith("_ci95") and (triad, term) not in FIELDS and values is not None \
                    and any(v is not None for v in values):
                dropped.append(f"noise.{triad}.{term}: no Kalibr field")
    return Export("\n".join(lines) + "\n", dropped)
