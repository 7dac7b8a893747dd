"""Calibration sets shared by the firmware-export tests (expressible and not)."""

from __future__ import annotations

import numpy as np

from workbench.calset import CalibrationSet, TriadCalibration, Unit
from workbench.model import ThermalModel, TriadModel

DEG = np.pi / 180
RANGES = {"gyro": 450 * DEG, "accel": 10 * 9.80665, "mag": 250.0}  # full scales, SI (industrial_mems)
T_RANGE = (-40.0, 85.0)


def expressible_set(t_ref_c: float = 25.0) -> CalibrationSet:
    """Everything PX4 and ArduPilot can hold: cubic bias polys, accel diag scale, symmetric soft iron."""
    gyro = TriadModel(bias=[0.01, -0.02, 0.005],
                      thermal=ThermalModel(t_ref_c, [[0, 2e-4, 3e-6, 4e-8], [0, -1e-4, 2e-6, -3e-8],
                                                     [0, 1e-4, -2e-6, 5e-8]]))
    accel = TriadModel(bias=[0.05, -0.03, 0.08], scale_misalignment=np.diag([2e-3, -1.5e-3, 1e-3]),
                       thermal=ThermalModel(t_ref_c, [[0, 1e-3, 5e-5, 1e-6], [0, -2e-3, 4e-5, -1e-6],
                                                      [0, 1e-3, -3e-5, 2e-6]]))
    soft = np.array([[0.04, 0.01, -0.02], [0.01, -0.03, 0.015], [-0.02, 0.015, 0.05]])
    mag = TriadModel(bias=[10.0, -7.0, 4.0], scale_misalignment=soft)
    triads = {"gyro": TriadCalibration(gyro, thermal_range_c=T_RANGE),
              "accel": TriadCalibration(accel, thermal_range_c=T_RANGE),
              "mag": TriadCalibration(mag, field_norm_ut=48.0)}
    return CalibrationSet(Unit("SN-42", "industrial_mems"), triads)


def true_inputs(triad: str, n: int, seed: int) -> np.ndarray:
    """Random true inputs (n, 3) within half the full scale."""
    return np.random.default_rng(seed).uniform(-0.5, 0.5, (n, 3)) * RANGES[triad]


def read_params(text: str, sep: str) -> dict[str, float]:
    """Parameter name -> value from an exported file (``#`` comments skipped)."""
    out = {}
    for line in text.splitlines():
        if not line or line.startswith("#"):
            continue
        parts = line.split(sep)
        name, value = (parts[2], parts[3]) if sep == "\t" else (parts[0], parts[1])
        out[name] = float(value)
    return out
