"""PX4 parameter file (QGroundControl ``.params``): thermal and sensor calibration parameters.

PX4 convention (PX4 user guide, "Thermal Calibration and Compensation", and the sensor
calibration library ``src/lib/sensor_calibration``), per triad instance 0:

* thermal offset ``O(T) = X0 + X1 d + X2 d^2 + X3 d^3`` with ``d = clamp(T, TMIN, TMAX) - TREF``
  (``TC_A0_Xn_i``, ``TC_G0_Xn_i``, axis ``i`` = 0, 1, 2; ``TC_*0_TREF``, ``TMIN``, ``TMAX``, °C);
* accelerometer ``corrected = (raw - O(T) - CAL_ACC0_{X,Y,Z}OFF) * CAL_ACC0_{X,Y,Z}SCALE``
  (m/s^2); gyro ``corrected = raw - O(T) - CAL_GYRO0_{X,Y,Z}OFF`` (rad/s, no scale);
* magnetometer ``corrected = S @ (raw - CAL_MAG0_{X,Y,Z}OFF)`` in gauss, ``S`` symmetric with
  diagonal ``CAL_MAG0_{X,Y,Z}SCALE`` and off-diagonal ``CAL_MAG0_{X,Y,Z}ODIAG`` = (S01, S02, S12).

From our model (``measured = (I + M) x + b(T)``): ``X0..X3`` = the bias polynomial with the
constant bias added to ``X0`` (with thermal compensation the offset lives in ``X0``, as PX4's
own calibration does, and ``CAL_*OFF`` = 0), ``SCALE = 1 / (1 + M_ii)``, mag offset = hard iron
/ 100 (µT -> gauss), ``S`` the symmetric factor of ``inv(I + M)``. Sensor frame = body frame
(board rotation none) is assumed; device ids (``*_ID``) must be set on the vehicle.
"""

from __future__ import annotations

import numpy as np

from workbench.calset import CalibrationSet
from workbench.exports._firmware import bias_cubic, fmt, header, inertial_dropped, soft_iron
from workbench.registry import Export
from workbench.units import factor

FORMAT = "px4"
SUFFIX = ".params"
DESCRIPTION = "PX4 parameter file: TC_A0_*/TC_G0_* thermal polynomials, CAL_ACC0/GYRO0/MAG0 offsets and scales"

_FLOAT, _INT = 9, 6  # MAV_PARAM_TYPE_REAL32, MAV_PARAM_TYPE_INT32
_TC = {"accel": ("A", "CAL_ACC0"), "gyro": ("G", "CAL_GYRO0")}


def _inertial(calset: CalibrationSet, triad: str, dropped: list[str]) -> list[tuple[str, float, int]]:
    m = calset.triads[triad].model
    letter, cal = _TC[triad]
    rows: list[tuple[str, float, int]] = []
    cubic = bias_cubic(calset, triad, dropped)
    offset = m.bias.copy()
    if cubic is not None:
        coeffs, t_ref, t_min, t_max = cubic
        coeffs = coeffs.copy()
        coeffs[:, 0] += m.bias
        offset = np.zeros(3)
        rows.append((f"TC_{letter}_ENABLE", 1, _INT))
        rows += [(f"TC_{letter}0_X{k}_{i}", coeffs[i, k], _FLOAT) for k in range(4) for i in range(3)]
        rows += [(f"TC_{letter}0_TREF", t_ref, _FLOAT), (f"TC_{letter}0_TMIN", t_min, _FLOAT),
                 (f"TC_{letter}0_TMAX", t_max, _FLOAT)]
    rows += [(f"{cal}_{a}OFF", offset[i], _FLOAT) for i, a in enumerate("XYZ")]
    if triad == "accel":
        scale = 1.0 / (1.0 + np.diag(m.scale_misalignment))
        rows += [(f"{cal}_{a}SCALE", scale[i], _FLOAT) for i, a in enumerate("XYZ")]
    dropped += inertial_dropped(calset, triad, scale_supported=triad == "accel", target="PX4")
    return rows


def _mag(calset: CalibrationSet, dropped: list[str]) -> list[tuple[str, float, int]]:
    mag = soft_iron(calset, dropped, "PX4")
    if mag is None:
        return []
    hard, sym = mag
    off = hard / factor("gauss")
    odiag = (sym[0, 1], sym[0, 2], sym[1, 2])
    return ([(f"CAL_MAG0_{a}OFF", off[i], _FLOAT) for i, a in enumerate("XYZ")]
            + [(f"CAL_MAG0_{a}SCALE", sym[i, i], _FLOAT) for i, a in enumerate("XYZ")]
            + [(f"CAL_MAG0_{a}ODIAG", odiag[i], _FLOAT) for i, a in enumerate("XYZ")])


def parameters(calset: CalibrationSet) -> tuple[list[tuple[str, float, int]], list[str]]:
    """(name, value, MAV type) rows of the set and the dropped lines."""
    dropped: list[str] = []
    rows: list[tuple[str, float, int]] = []
    for triad in ("accel", "gyro"):
        if triad in calset.triads:
            rows += _inertial(calset, triad, dropped)
    rows += _mag(calset, dropped)
    return rows, dropped


def export(calset: CalibrationSet) -> Export:
    """QGroundControl parameter file text (tab separated: vehicle, component, name, value, type)."""
    rows, dropped = parameters(calset)
    head = header(calset, "PX4") + [
        "# sensor frame = body frame assumed; set TC_A0_ID, TC_G0_ID, CAL_ACC0_ID, CAL_GYRO0_ID, CAL_MAG0_ID "
        "to the device ids of the vehicle",
        "#", "# Vehicle-Id\tComponent-Id\tName\tValue\tType"]
    body = [f"1\t1\t{name}\t{int(value) if kind == _INT else fmt(value)}\t{kind}" for name, value, kind in rows]
    return Export("\n".join(head + body) + "\n", dropped)
