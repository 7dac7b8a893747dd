"""Lab units at the edges: conversions between SI and the units labs report in.

Every function converts *from SI* (``to_*``) or *to SI* (``from_*``); the name says the lab
unit. Used by summaries, figures, reports, import profiles and exports only.
"""

from __future__ import annotations

import numpy as np

G0 = 9.80665  # m/s^2, standard gravity (the unit 'g' of datasheets)
DEG = np.pi / 180.0
HOUR = 3600.0

# factor: value_in_lab_unit = value_SI / factor
_FACTORS = {
    "rad/s": 1.0, "deg/s": DEG, "deg/h": DEG / HOUR, "rad": 1.0, "deg": DEG, "mrad": 1e-3,
    "arcsec": DEG / 3600.0,
    "m/s^2": 1.0, "m/s": 1.0, "g": G0, "mg": G0 * 1e-3, "ug": G0 * 1e-6,
    "rad/s/sqrt(Hz)": 1.0, "deg/sqrt(h)": DEG / np.sqrt(HOUR), "deg/h/sqrt(Hz)": DEG / HOUR,
    "m/s^2/sqrt(Hz)": 1.0, "m/s/sqrt(h)": 1.0 / np.sqrt(HOUR), "ug/sqrt(Hz)": G0 * 1e-6,
    "rad/s^2/sqrt(Hz)": 1.0, "deg/h/sqrt(h)": DEG / HOUR / np.sqrt(HOUR),
    "m/s^3/sqrt(Hz)": 1.0, "m/s/h/sqrt(h)": 1.0 / HOUR / np.sqrt(HOUR),
    "deg/h/h": DEG / HOUR / HOUR, "m/s^3": 1.0,
    "ut": 1.0, "uT": 1.0, "nT": 1e-3, "gauss": 100.0, "mgauss": 0.1, "T": 1e6,
    "ppm": 1e-6, "%": 1e-2, "1": 1.0,
}
LABELS = {"deg/sqrt(h)": "°/√h", "deg/h": "°/h", "deg/s": "°/s", "ug/sqrt(Hz)": "µg/√Hz", "ug": "µg",
          "uT": "µT", "deg": "°", "m/s/sqrt(h)": "m/s/√h", "deg/h/sqrt(h)": "°/h/√h", "m/s/h/sqrt(h)": "m/s/h/√h",
          "deg/h/h": "°/h²", "m/s^3": "m/s³"}


def factor(unit: str) -> float:
    """SI value of one ``unit`` (e.g. ``factor('deg/h')`` = 4.848e-6 rad/s)."""
    try:
        return _FACTORS[unit]
    except KeyError:
        raise ValueError(f"unknown unit {unit!r} (known: {', '.join(sorted(_FACTORS))})") from None


def to_unit(value_si, unit: str):
    """Convert an SI value (scalar or array) to ``unit``."""
    return np.asarray(value_si, float) / factor(unit) if np.ndim(value_si) else float(value_si) / factor(unit)


def from_unit(value, unit: str):
    """Convert a value in ``unit`` to SI."""
    return np.asarray(value, float) * factor(unit) if np.ndim(value) else float(value) * factor(unit)


def label(unit: str) -> str:
    """Display label of a unit (``deg/sqrt(h)`` -> ``°/√h``)."""
    return LABELS.get(unit, unit)


def fmt(value_si, unit: str, digits: int = 4) -> str:
    """``value_si`` shown in ``unit`` with its label, e.g. ``'0.2001 °/√h'``; NaN -> 'not observed'."""
    if value_si is None or not np.isfinite(value_si):
        return "not observed"
    return f"{to_unit(value_si, unit):.{digits}g} {label(unit)}"


# Natural display unit of each triad's quantities, used by summaries and the dashboard.
DISPLAY = {
    "gyro": {"bias": "deg/h", "noise_white": "deg/sqrt(h)", "bias_instability": "deg/h", "rrw": "deg/h/sqrt(h)",
             "quantization": "arcsec", "residual": "deg/s"},
    "accel": {"bias": "mg", "noise_white": "ug/sqrt(Hz)", "bias_instability": "ug", "rrw": "m/s/h/sqrt(h)",
              "quantization": "m/s", "residual": "mg"},
    "mag": {"bias": "uT", "residual": "uT"},
}
