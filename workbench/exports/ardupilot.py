"""ArduPilot parameter file (``.parm``, ``NAME,VALUE`` lines): IMU temperature calibration and compass.

ArduPilot convention (``libraries/AP_InertialSensor/AP_InertialSensor_tempcal.cpp`` and
``AP_InertialSensor_Backend.cpp``, ``libraries/AP_Compass/AP_Compass_Backend.cpp``), IMU 1:

* temperature correction ``v -= P(clamp(T) - 35) - P(clamp(T_cal) - 35)`` with
  ``P(d) = (c1 d + c2 d^2 + c3 d^3) * 1e-6``: a fixed reference of 35 °C, no constant term,
  coefficients ``INS_TCAL1_ACCk_{X,Y,Z}`` / ``INS_TCAL1_GYRk_{X,Y,Z}`` stored scaled by 1e6,
  ``clamp`` to ``INS_TCAL1_TMIN..TMAX``, ``T_cal`` = ``INS_ACC1_CALTEMP`` / ``INS_GYR1_CALTEMP``;
* accelerometer ``v = (v - INS_ACCOFFS) * INS_ACCSCAL`` (m/s^2); gyro ``v -= INS_GYROFFS`` (rad/s);
* compass ``m = D @ (raw + COMPASS_OFS)`` in milligauss: the offset is *added*, ``D`` symmetric
  with diagonal ``COMPASS_DIA_{X,Y,Z}`` and off-diagonal ``COMPASS_ODI_{X,Y,Z}`` = (D01, D02, D12).

From our model: ``T_cal`` = the set's t_ref (clamped into the valid range), the offsets = the
total bias at ``T_cal``, and ``P`` = our bias polynomial re-expanded about 35 °C without its
constant term, so ``P(T) - P(T_cal)`` equals our bias change from ``T_cal``;
``INS_ACCSCAL = 1 / (1 + M_ii)``; ``COMPASS_OFS`` = -hard iron x 10 (µT -> mG); ``D`` the
symmetric factor of ``inv(I + M)``. Sensor frame = body frame assumed. ArduPilot re-learns
gyro offsets at boot unless ``INS_GYRO_CAL`` = 0.
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import polynomial as npoly

from workbench.calset import CalibrationSet
from workbench.exports._firmware import bias_cubic, fmt, header, inertial_dropped, soft_iron
from workbench.registry import Export
from workbench.units import factor

FORMAT = "ardupilot"
SUFFIX = ".parm"
DESCRIPTION = "ArduPilot .parm: INS_TCAL1_* polynomials, INS_ACCOFFS/ACCSCAL/GYROFFS, COMPASS_OFS/DIA/ODI"

TEMP_REFERENCE_C = 35.0  # fixed reference of ArduPilot's temperature calibration
COEFF_SCALE = 1.0e6  # INS_TCAL coefficients are stored multiplied by this
_NAMES = {"accel": ("ACC", "INS_ACCOFFS", "INS_ACC1_CALTEMP"), "gyro": ("GYR", "INS_GYROFFS", "INS_GYR1_CALTEMP")}


def shift_polynomial(coeffs: np.ndarray, shift: float) -> np.ndarray:
    """Re-expand per-axis polynomials ``sum_k c_k x^k`` in ``z = x - shift``; (3, K) -> (3, K)."""
    out = np.zeros_like(coeffs)
    for i, row in enumerate(coeffs):
        # p(x) with x = z + shift: compose with the linear polynomial (shift + z)
        acc = np.zeros(1)
        for c in row[::-1]:  # Horner in polynomial arithmetic
            acc = npoly.polyadd(npoly.polymul(acc, [shift, 1.0]), [c])
        out[i, : len(acc)] = acc[: coeffs.shape[1]]
    return out


def _inertial(calset: CalibrationSet, triad: str, dropped: list[str], tcal: dict) -> list[tuple[str, float]]:
    m = calset.triads[triad].model
    key, offs_name, caltemp_name = _NAMES[triad]
    cubic = bias_cubic(calset, triad, dropped)
    rows: list[tuple[str, float]] = []
    offset = m.bias.copy()
    if cubic is not None:
        coeffs, t_ref, t_min, t_max = cubic
        t_cal = float(np.clip(t_ref, t_min, t_max))
        offset = offset + np.array([np.polyval(c[::-1], t_cal - t_ref) for c in coeffs])
        about35 = shift_polynomial(coeffs, TEMP_REFERENCE_C - t_ref)
        tcal.setdefault("range", (t_min, t_max))
        if tcal["range"] != (t_min, t_max):
            kept = f"{tcal['range'][0]:.1f}..{tcal['range'][1]:.1f}"
            dropped.append(f"{triad}: valid range {t_min:.1f}..{t_max:.1f} °C differs from the other triad's; "
                           f"ArduPilot has one INS_TCAL1_TMIN/TMAX (kept {kept})")
        rows += [(f"INS_TCAL1_{key}{k}_{a}", about35[i, k] * COEFF_SCALE) for k in (1, 2, 3)
                 for i, a in enumerate("XYZ")]
        rows.append((caltemp_name, t_cal))
    rows += [(f"{offs_name}_{a}", offset[i]) for i, a in enumerate("XYZ")]
    if triad == "accel":
        scale = 1.0 / (1.0 + np.diag(m.scale_misalignment))
        rows += [(f"INS_ACCSCAL_{a}", scale[i]) for i, a in enumerate("XYZ")]
    dropped += inertial_dropped(calset, triad, scale_supported=triad == "accel", target="ArduPilot")
    return rows


def _compass(calset: CalibrationSet, dropped: list[str]) -> list[tuple[str, float]]:
    mag = soft_iron(calset, dropped, "ArduPilot")
    if mag is None:
        return []
    hard, sym = mag
    ofs = -hard / factor("mgauss")
    odi = (sym[0, 1], sym[0, 2], sym[1, 2])
    return ([(f"COMPASS_OFS_{a}", ofs[i]) for i, a in enumerate("XYZ")]
            + [(f"COMPASS_DIA_{a}", sym[i, i]) for i, a in enumerate("XYZ")]
            + [(f"COMPASS_ODI_{a}", odi[i]) for i, a in enumerate("XYZ")])


def parameters(calset: CalibrationSet) -> tuple[list[tuple[str, float]], list[str]]:
    """(name, value) rows of the set and the dropped lines."""
    dropped: list[str] = []
    tcal: dict = {}
    rows: list[tuple[str, float]] = []
    for triad in ("accel", "gyro"):
        if triad in calset.triads:
            rows += _inertial(calset, triad, dropped, tcal)
    if "range" in tcal:
        rows = [("INS_TCAL1_ENABLE", 1), ("INS_TCAL1_TMIN", tcal["range"][0]),
                ("INS_TCAL1_TMAX", tcal["range"][1])] + rows
    rows += _compass(calset, dropped)
    return rows, dropped


def export(calset: CalibrationSet) -> Export:
    """``.parm`` text (``NAME,VALUE`` per line, ``#`` comments)."""
    rows, dropped = parameters(calset)
    head = header(calset, "ArduPilot") + [
        "# sensor frame = body frame assumed (AHRS_ORIENTATION none); IMU 1 and compass 1;",
        "# ArduPilot re-learns INS_GYROFFS at boot unless INS_GYRO_CAL = 0"]
    body = [f"{name},{int(value) if name.endswith('ENABLE') else fmt(value)}" for name, value in rows]
    return Export("\n".join(head + body) + "\n", dropped)
