"""Lab units at the edges: conversions between SI and the units labs report in, and one vocabulary.

Every function converts *from SI* (``to_*``) or *to SI* (``from_*``); the name says the lab
unit. Used by summaries, figures, reports, import profiles and exports only.

:data:`QUANTITIES` is the one display vocabulary: the lab unit of every quantity a calibration
set holds, per triad (gyro bias °/h, accel bias mg, scale factor ppm, misalignment mrad, ...).
The CLI, the dashboard, the certificate and the exporters' dropped lists take their units from
:func:`unit_of` / :func:`show`; a quantity without an entry is an error, not an SI number.
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
    "m": 1.0, "cm": 1e-2, "mm": 1e-3, "cm/s": 1e-2,
    "m/s^2": 1.0, "m/s": 1.0, "mm/s": 1e-3, "g": G0, "mg": G0 * 1e-3, "ug": G0 * 1e-6,
    "rad/s/sqrt(Hz)": 1.0, "deg/sqrt(h)": DEG / np.sqrt(HOUR), "deg/h/sqrt(Hz)": DEG / HOUR,
    "m/s^2/sqrt(Hz)": 1.0, "m/s/sqrt(h)": 1.0 / np.sqrt(HOUR), "ug/sqrt(Hz)": G0 * 1e-6,
    "rad/s^2/sqrt(Hz)": 1.0, "deg/h/sqrt(h)": DEG / HOUR / np.sqrt(HOUR),
    "m/s^3/sqrt(Hz)": 1.0, "m/s/h/sqrt(h)": 1.0 / HOUR / np.sqrt(HOUR), "ug/sqrt(h)": G0 * 1e-6 / np.sqrt(HOUR),
    "deg/h/h": DEG / HOUR / HOUR, "m/s^3": 1.0, "ug/h": G0 * 1e-6 / HOUR,
    "ut": 1.0, "uT": 1.0, "nT": 1e-3, "gauss": 100.0, "mgauss": 0.1, "T": 1e6,
    "ppm": 1e-6, "%": 1e-2, "1": 1.0,
    # nonlinearity k of measured = x + k x^2 and g-sensitivity (rad/s per m/s^2)
    "ppm/(deg/s)": 1e-6 / DEG, "ug/g^2": G0 * 1e-6 / G0 ** 2, "ppm/uT": 1e-6, "deg/h/g": DEG / HOUR / G0,
    "degC": 1.0, "s": 1.0, "Hz": 1.0,
    # the other spellings sensor-grade fixtures use (workbench.grade_fixtures)
    "m/s/h": 1.0 / HOUR, "deg/s/sqrt(Hz)": DEG, "mg/sqrt(Hz)": G0 * 1e-3, "uT/sqrt(Hz)": 1.0, "nT/sqrt(Hz)": 1e-3,
    "rad/s/sqrt(s)": 1.0, "ug/sqrt(s)": G0 * 1e-6, "m/s^2/sqrt(s)": 1.0, "uT/sqrt(s)": 1.0, "urad": 1e-6,
    "uT*s": 1.0, "deg/s/g": DEG / G0, "rad/s/(m/s^2)": 1.0,
    # virtual-lab imperfections (a grade's imperfections block): scale-factor drift, noise per °C
    "ppm/h": 1e-6 / HOUR, "%/h": 1e-2 / HOUR, "1/degC": 1.0, "%/degC": 1e-2,
}
# the SI unit each lab unit is a multiple of (for checks such as "is this a unit of rate?")
_SI_UNITS = {
    "rad/s": ("rad/s", "deg/s", "deg/h"), "rad": ("rad", "deg", "mrad", "urad", "arcsec"),
    "m/s^2": ("m/s^2", "g", "mg", "ug"), "uT": ("uT", "ut", "nT", "gauss", "mgauss", "T"),
    "m/s": ("m/s", "cm/s", "mm/s"), "m": ("m", "cm", "mm"), "degC": ("degC",), "s": ("s",), "Hz": ("Hz",),
    "1": ("1", "ppm", "%"),
}
_SI_OF = {u: si for si, members in _SI_UNITS.items() for u in members}


def si_unit(unit: str) -> str | None:
    """The SI unit ``unit`` is a multiple of (``'deg/h'`` -> ``'rad/s'``, ``'gauss'`` -> ``'uT'``); None for a
    compound unit outside the table (noise densities, ratios of rates)."""
    factor(unit)  # an unknown unit is an error, not None
    return _SI_OF.get(unit)


def units_of(si: str) -> tuple[str, ...]:
    """The lab units of the SI unit ``si`` (``'rad/s'`` -> ``('rad/s', 'deg/s', 'deg/h')``)."""
    return _SI_UNITS[si]


LABELS = {"deg/sqrt(h)": "°/√h", "deg/h": "°/h", "deg/s": "°/s", "ug/sqrt(Hz)": "µg/√Hz", "ug": "µg",
          "uT": "µT", "ut": "µT", "deg": "°", "m/s/sqrt(h)": "m/s/√h", "deg/h/sqrt(h)": "°/h/√h",
          "m/s/h/sqrt(h)": "m/s/h/√h", "ug/sqrt(h)": "µg/√h", "deg/h/h": "°/h²", "m/s^3": "m/s³", "ug/h": "µg/h",
          "m/s^2": "m/s²", "ppm/(deg/s)": "ppm/(°/s)", "ug/g^2": "µg/g²", "ppm/uT": "ppm/µT", "deg/h/g": "°/h/g",
          "degC": "°C", "1": ""}

# The display vocabulary: (triad, quantity) -> lab unit. Thermal polynomial coefficient k is
# shown in the unit of its quantity per °C^k (see thermal_label).
QUANTITIES: dict[tuple[str, str], str] = {
    ("gyro", "bias"): "deg/h", ("accel", "bias"): "mg", ("mag", "bias"): "uT",
    ("gyro", "scale_factor"): "ppm", ("accel", "scale_factor"): "ppm", ("mag", "scale_factor"): "ppm",
    ("gyro", "misalignment"): "mrad", ("accel", "misalignment"): "mrad", ("mag", "misalignment"): "mrad",
    ("gyro", "nonlinearity"): "ppm/(deg/s)", ("accel", "nonlinearity"): "ug/g^2", ("mag", "nonlinearity"): "ppm/uT",
    ("gyro", "g_sensitivity"): "deg/h/g",
    ("gyro", "arw"): "deg/sqrt(h)", ("accel", "vrw"): "ug/sqrt(Hz)",
    ("gyro", "bias_instability"): "deg/h", ("accel", "bias_instability"): "ug",
    ("gyro", "rrw"): "deg/h/sqrt(h)", ("accel", "rrw"): "ug/sqrt(h)",
    ("gyro", "quantization"): "arcsec", ("accel", "quantization"): "mm/s",
    ("gyro", "rate_ramp"): "deg/h/h", ("accel", "rate_ramp"): "ug/h",
    ("gyro", "residual"): "deg/s", ("accel", "residual"): "mg", ("mag", "residual"): "uT",
    ("mag", "field_norm"): "uT",
    ("gyro", "thermal.bias_poly"): "deg/h", ("accel", "thermal.bias_poly"): "mg", ("mag", "thermal.bias_poly"): "uT",
    ("gyro", "thermal.scale_poly"): "ppm", ("accel", "thermal.scale_poly"): "ppm", ("mag", "thermal.scale_poly"): "ppm",
}
# the Allan-fit names of the noise terms (white noise is ARW for a gyro, VRW for an accelerometer)
_ALIASES = {("gyro", "white"): "arw", ("accel", "white"): "vrw", ("gyro", "noise_white"): "arw",
            ("accel", "noise_white"): "vrw"}


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
    return f"{to_unit(value_si, unit):.{digits}g} {label(unit)}".rstrip()


def quantity_key(triad: str, quantity: str) -> tuple[str, str]:
    """The vocabulary key of ``quantity`` of ``triad`` (Allan names such as ``white`` resolved)."""
    return triad, _ALIASES.get((triad, quantity), quantity)


def unit_of(triad: str, quantity: str) -> str:
    """Lab unit of ``quantity`` (``bias``, ``scale_factor``, ``misalignment``, ``arw``, ...) of ``triad``.

    Raises KeyError naming the quantity when the vocabulary has no entry: every displayed
    quantity must have one.
    """
    key = quantity_key(triad, quantity)
    if key not in QUANTITIES:
        raise KeyError(f"units.QUANTITIES has no entry for {triad} {quantity}")
    return QUANTITIES[key]


def fit_unit(quantity: str) -> str:
    """Lab unit of a thermal fit's quantity ``'<triad>.bias'`` / ``'<triad>.scale'`` (``gyro.bias`` -> deg/h)."""
    triad, what = quantity.split(".", 1)
    return unit_of(triad, "scale_factor" if what == "scale" else "bias")


def thermal_label(triad: str, field: str, k: int) -> str:
    """Label of thermal coefficient ``k`` of ``field`` (``bias_poly``/``scale_poly``): ``'°/h/°C²'``."""
    base = label(unit_of(triad, f"thermal.{field}"))
    return base if k == 0 else f"{base}/°C" if k == 1 else f"{base}/°C{_SUPERSCRIPT.get(k, '^' + str(k))}"


_SUPERSCRIPT = {2: "²", 3: "³", 4: "⁴", 5: "⁵", 6: "⁶", 7: "⁷", 8: "⁸", 9: "⁹"}


def show(triad: str, quantity: str, value_si, sigma_si=None, digits: int = 4) -> str:
    """A quantity in its lab unit, one unit per figure: ``'0.21 ± 0.012 °/h'``.

    ``sigma_si`` NaN reads "σ not observed"; a NaN / None value reads "not observed".
    """
    return pm(value_si, sigma_si, unit_of(triad, quantity), digits)


def pm(value_si, sigma_si, unit: str, digits: int = 4) -> str:
    """``value_si ± sigma_si`` (SI) in ``unit``, the unit written once: ``'-2.22 ± 0.005 µT'``.

    ``sigma_si`` None: the value alone; NaN: "(σ not observed)"; a NaN / None value: "not observed".
    """
    if value_si is None or not np.isfinite(float(value_si)):
        return "not observed"
    value = f"{to_unit(float(value_si), unit):.{digits}g}"
    if sigma_si is None:
        return f"{value} {label(unit)}".rstrip()
    sig = float(sigma_si)
    sig_text = f"± {to_unit(sig, unit):.2g}" if np.isfinite(sig) else "(σ not observed)"
    return f"{value} {sig_text} {label(unit)}".rstrip()


def column(triad: str, quantity: str) -> str:
    """A table header naming the quantity and its unit: ``'bias (°/h)'``."""
    return f"{quantity.replace('_', ' ')} ({label(unit_of(triad, quantity))})"


def field_quantity(field: str, index: tuple[int, ...]) -> str:
    """The vocabulary quantity of element ``index`` of a calibration field (M splits into scale factor
    on its diagonal and misalignment off it)."""
    if field == "scale_misalignment":
        return "scale_factor" if len(index) == 2 and index[0] == index[1] else "misalignment"
    return field

