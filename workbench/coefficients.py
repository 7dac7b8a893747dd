"""Every coefficient of a calibration set as display rows in the lab units of ``workbench.units``.

One list of rows, shared by ``workbench sets show``, the dashboard's Calibration sets page and
the certificate, so the three show the same quantities in the same units: bias, scale factor,
misalignment, nonlinearity, g-sensitivity, thermal polynomials (per °C^k), the magnetometer's
field norm and the noise terms with their 95 % intervals. Values and 1-sigma uncertainties
are converted from SI here; NaN sigma means "not observed".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench import units
from workbench.calset import CalibrationSet, TriadCalibration

AXES = "xyz"
TRIAD_TITLES = {"gyro": "Gyroscopes", "accel": "Accelerometers", "mag": "Magnetometer"}


@dataclass(frozen=True)
class Row:
    """One displayed coefficient: ``value`` and ``sigma`` (1-sigma, NaN = not observed) in ``unit``."""

    triad: str
    quantity: str  # a key of units.QUANTITIES (second part)
    field: str  # the calibration field (bias, scale_misalignment, thermal.bias_poly, field_norm, ...)
    index: tuple[int, ...]  # element index within the field
    name: str  # e.g. "bias x", "misalignment M[x,y]", "bias thermal °C¹ y"
    value: float
    sigma: float
    unit: str  # display label, e.g. "°/h"

    @property
    def observed(self) -> bool:
        """True when the data determined this coefficient (finite sigma)."""
        return bool(np.isfinite(self.sigma))


@dataclass(frozen=True)
class NoiseRow:
    """One noise term of one axis in its lab unit; ``ci95`` the 95 % interval (None when absent)."""

    triad: str
    term: str
    axis: str
    value: float  # NaN = not observed
    ci95: tuple[float, float] | None
    unit: str


def _conv(triad: str, quantity: str, value_si: float) -> float:
    return float(units.to_unit(value_si, units.unit_of(triad, quantity)))


def _label(triad: str, quantity: str) -> str:
    return units.label(units.unit_of(triad, quantity))


def element_name(field: str, index: tuple[int, ...]) -> str:
    """Readable name of one element of a calibration field: ``scale factor y``, ``misalignment M[x,z]``."""
    if field == "scale_misalignment":
        i, j = index
        return f"scale factor {AXES[i]}" if i == j else f"misalignment M[{AXES[i]},{AXES[j]}]"
    if field == "g_sensitivity":
        return f"g-sensitivity G[{AXES[index[0]]},{AXES[index[1]]}]"
    if field.startswith("thermal."):
        what = "bias" if field.endswith("bias_poly") else "scale factor"
        return f"{what} thermal c{index[1]} {AXES[index[0]]}"
    return f"{field.replace('_', ' ')} {AXES[index[0]]}" if index else field


def element_unit(triad: str, field: str, index: tuple[int, ...]) -> tuple[str, float]:
    """(display label, SI value of one display unit) of one element of a calibration field."""
    if field.startswith("thermal."):
        unit = units.unit_of(triad, field)
        return units.thermal_label(triad, field.split(".")[1], index[1]), units.factor(unit)
    unit = units.unit_of(triad, units.field_quantity(field, index))
    return units.label(unit), units.factor(unit)


def _held_at_zero(value: np.ndarray, sigma: np.ndarray) -> bool:
    """A thermal c0 column fixed at zero (the bias / scale factor at t_ref is the model's own)."""
    return bool(np.all(value == 0) and np.all(np.nan_to_num(sigma, nan=0.0) == 0))


def _field_rows(triad: str, tc: TriadCalibration, field: str, value: np.ndarray) -> list[Row]:
    sigma = tc.sigma_of(field)
    rows = []
    for idx in np.ndindex(value.shape):
        if field.startswith("thermal.") and idx[1] == 0 and _held_at_zero(value[:, 0], sigma[:, 0]):
            continue
        label, f = element_unit(triad, field, idx)
        quantity = units.field_quantity(field, idx)
        rows.append(Row(triad, quantity, field, tuple(int(i) for i in idx), element_name(field, idx), float(value[idx]) / f,
                        float(sigma[idx]) / f if np.isfinite(sigma[idx]) else np.nan, label))
    return rows


def triad_rows(cal: CalibrationSet, triad: str) -> list[Row]:
    """All coefficients of ``triad`` in lab units (nonlinearity / g-sensitivity / thermal only when present)."""
    tc = cal.triads[triad]
    m = tc.model
    rows = _field_rows(triad, tc, "bias", m.bias)
    rows += _field_rows(triad, tc, "scale_misalignment", m.scale_misalignment)
    if np.any(m.nonlinearity) or "nonlinearity" in tc.sigma:
        rows += _field_rows(triad, tc, "nonlinearity", m.nonlinearity)
    if m.g_sensitivity is not None:
        rows += _field_rows(triad, tc, "g_sensitivity", m.g_sensitivity)
    if m.thermal is not None:
        for f in ("bias_poly", "scale_poly"):
            poly = getattr(m.thermal, f)
            if poly.shape[1]:
                rows += _field_rows(triad, tc, f"thermal.{f}", poly)
    if triad == "mag" and tc.field_norm_ut is not None:
        s = tc.field_norm_ut_sigma
        rows.append(Row(triad, "field_norm", "field_norm", (), "field norm", _conv(triad, "field_norm", tc.field_norm_ut),
                        np.nan if s is None else _conv(triad, "field_norm", s), _label(triad, "field_norm")))
    return rows


def thermal_reference(cal: CalibrationSet, triad: str) -> str | None:
    """'t_ref 23 °C, valid 5 .. 45 °C' of a triad's thermal model (None without one)."""
    tc = cal.triads[triad]
    if tc.model.thermal is None:
        return None
    text = f"polynomials in (T − t_ref), t_ref {tc.model.thermal.t_ref_c:g} °C "
    text += "; c_k per °C^k, c0 not listed where it is held at 0 (the value at t_ref is the coefficient above)"
    if tc.thermal_range_c is not None:
        text += f", valid {tc.thermal_range_c[0]:.1f} .. {tc.thermal_range_c[1]:.1f} °C"
    return text


def noise_rows(cal: CalibrationSet) -> list[NoiseRow]:
    """Every noise term of the set per axis, in its lab unit with its 95 % interval."""
    rows = []
    for triad, terms in cal.noise.items():
        for term, values in terms.items():
            if term.endswith("_ci95"):
                continue
            unit = units.unit_of(triad, term)
            ci = terms.get(term + "_ci95") or [None] * len(values)
            for i, v in enumerate(values):
                interval = ci[i] if i < len(ci) else None
                rows.append(NoiseRow(triad, term, AXES[i], np.nan if v is None else float(units.to_unit(v, unit)),
                                     None if interval is None else
                                     (float(units.to_unit(interval[0], unit)), float(units.to_unit(interval[1], unit))),
                                     units.label(unit)))
    return rows


def value_text(value: float, digits: int = 5) -> str:
    """A displayed number, '—' for NaN."""
    return "—" if not np.isfinite(value) else f"{value:.{digits}g}"


def sigma_text(sigma: float, k: float = 1.0) -> str:
    """k-sigma uncertainty to two significant digits ('140', '0.0061'; exponent only below 1e-4 or
    from 1e6 on), 'not observed' for NaN."""
    if not np.isfinite(sigma):
        return "not observed"
    u = k * sigma
    if u == 0 or not 1e-4 <= abs(u) < 1e6:
        return f"{u:.2g}"
    r = float(f"{u:.2g}")  # two significant digits (9.96 -> 10)
    return f"{r:.{max(1 - int(np.floor(np.log10(abs(r)))), 0)}f}"


def ci_text(ci: tuple[float, float] | None) -> str:
    """A 95 % interval 'lo .. hi' ('' when absent)."""
    return "" if ci is None else f"{ci[0]:.3g} .. {ci[1]:.3g}"
