"""Shared pieces of the autopilot exports (PX4, ArduPilot): what their simple models can hold.

Autopilots correct an inertial triad with per-axis offsets, per-axis scales and a cubic
bias polynomial in temperature; a magnetometer with an offset and a symmetric 3x3 matrix.
These helpers reduce a :class:`~workbench.model.TriadModel` to those pieces and list, one line
each, what the reduction cannot keep (the ``dropped`` list of an export).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import polar
from scipy.spatial.transform import Rotation

from workbench.calset import CalibrationSet
from workbench.model import TriadModel
from workbench.units import label, show, to_unit, unit_of

LAB = {triad: unit_of(triad, "bias") for triad in ("gyro", "accel", "mag")}  # the unit vocabulary


def header(calset: CalibrationSet, vendor: str) -> list[str]:
    """The first comment lines of a parameter file: which set of which unit it comes from."""
    return [f"# {vendor} parameters from workbench calibration set {calset.id}",
            f"# unit {calset.unit.serial} {calset.unit.model}".rstrip()]


def fmt(value: float) -> str:
    """A parameter value with enough digits to round-trip a float32 (and more)."""
    return f"{float(value):.10g}"


def bias_cubic(calset: CalibrationSet, triad: str, dropped: list[str]) -> tuple[np.ndarray, float, float, float] | None:
    """Cubic bias polynomial of ``triad`` in ``(T - t_ref)``: (coeffs (3, 4), t_ref, t_min, t_max) or None.

    A higher-order polynomial is replaced by its least-squares cubic over the valid range
    (Chebyshev nodes) and the largest deviation is reported in ``dropped``. A set without a
    valid temperature range is reported and the range collapses to ``t_ref``.
    """
    tc = calset.triads[triad]
    th = tc.model.thermal
    if th is None or th.bias_poly.shape[1] == 0:
        return None
    if tc.thermal_range_c is None:
        dropped.append(f"{triad}: thermal model has no valid range (t_min_c/t_max_c): TMIN = TMAX = t_ref, "
                       "so the firmware applies no temperature change")
        t_min = t_max = th.t_ref_c
    else:
        t_min, t_max = map(float, tc.thermal_range_c)
    poly = th.bias_poly
    if poly.shape[1] <= 4:
        return np.pad(poly, ((0, 0), (0, 4 - poly.shape[1]))), th.t_ref_c, t_min, t_max
    nodes = 0.5 * (t_min + t_max) + 0.5 * (t_max - t_min) * np.cos(np.pi * (np.arange(64) + 0.5) / 64)
    dt = nodes - th.t_ref_c
    full = th.bias_shift(nodes)
    vander = dt[:, None] ** np.arange(4)
    cubic = np.linalg.lstsq(vander, full, rcond=None)[0].T
    dev = np.abs(vander @ cubic.T - full).max()
    dropped.append(f"{triad}: bias polynomial of order {poly.shape[1] - 1} > 3 replaced by its least-squares cubic "
                   f"over {t_min:.1f}..{t_max:.1f} °C (max deviation {to_unit(dev, LAB[triad]):.3g} "
                   f"{label(LAB[triad])})")
    return cubic, th.t_ref_c, t_min, t_max


def inertial_dropped(calset: CalibrationSet, triad: str, scale_supported: bool, target: str) -> list[str]:
    """What an offset(+scale)+cubic-bias firmware model loses from ``triad`` (one line each)."""
    m: TriadModel = calset.triads[triad].model
    out = []
    off = m.scale_misalignment - np.diag(np.diag(m.scale_misalignment))
    if np.any(off):
        worst = show(triad, "misalignment", np.abs(off).max(), digits=3)
        out.append(f"{triad}: misalignment (off-diagonal M, max {worst}): {target} has no cross-axis terms")
    if not scale_supported and np.any(np.diag(m.scale_misalignment)):
        worst = show(triad, "scale_factor", np.abs(np.diag(m.scale_misalignment)).max(), digits=3)
        out.append(f"{triad}: scale factor (diag M, max {worst}): {target} has no {triad} scale parameter")
    if np.any(m.nonlinearity):
        out.append(f"{triad}: quadratic nonlinearity: {target} has no such term")
    if m.g_sensitivity is not None and np.any(m.g_sensitivity):
        out.append(f"{triad}: g-sensitivity G: {target} has no such term")
    th = m.thermal
    if th is not None and th.scale_poly.shape[1] and np.any(th.scale_poly):
        out.append(f"{triad}: scale-factor temperature polynomial (order {th.scale_poly.shape[1] - 1}): {target} keeps "
                   "bias polynomials only")
    hyst = calset.notes.get("thermal", {}).get(triad, {}) if isinstance(calset.notes.get("thermal"), dict) else {}
    if any(any(v.get("hysteresis_modelled", [])) for v in hyst.values() if isinstance(v, dict)):
        out.append(f"{triad}: thermal hysteresis term (up/down branch): {target} has no such term")
    return out


def soft_iron(calset: CalibrationSet, dropped: list[str], target: str) -> tuple[np.ndarray, np.ndarray] | None:
    """Magnetometer (hard iron (3,) µT, symmetric correction matrix (3, 3)) or None.

    The correction ``inv(I + M)`` is split as ``R @ S`` (polar decomposition, S symmetric
    positive definite); autopilots hold S only, so a rotation R is reported as dropped.
    """
    if "mag" not in calset.triads:
        return None
    m = calset.triads["mag"].model
    corr = np.linalg.inv(m.gain)
    rot, sym = polar(corr)  # corr = rot @ sym
    angle = np.degrees(Rotation.from_matrix(rot).magnitude())
    if angle > 1e-6:
        dropped.append(f"mag: rotation part of the soft-iron correction ({angle:.3g}°): {target} holds a "
                       "symmetric matrix only (kept: its symmetric factor)")
    if m.thermal is not None:
        dropped.append(f"mag: temperature model: {target} has no magnetometer thermal terms")
    return m.bias, 0.5 * (sym + sym.T)
