"""Sensor grades: datasheet-like fixtures (``fixtures/units/*.yaml``) and units drawn from them.

A grade (:class:`SensorSpec`) holds, per triad, the 1-sigma spread of each deterministic
error (bias, scale factor, misalignment, nonlinearity, g-sensitivity, temperature
coefficients of bias and scale factor), the noise terms (:class:`NoiseSpec`), the range and
the output resolution. YAML keys carry their lab unit (``bias_deg_per_h``, ``arw_deg_per_sqrt_h``,
``scale_factor_ppm``, ...); :func:`load_spec` converts everything to SI.
:func:`draw_unit` draws one unit (:class:`UnitTruth`) from a grade with a seed: each
deterministic coefficient is ``sigma * N(0, 1)``, so two seeds give two different units.
The noise terms of a unit are the grade's (the Allan terms the datasheet states).

The key reference is docs/grades.md (keys, units, the grades and their sources: thesis
tables 1.1, 1.2, 2.1, 4.1; paper 001 tables 3-1 and 5-1; paper 004 sec. 4).
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from workbench.errors import CalibrationFormatError
from workbench.grade_fixtures import grade_names, load_spec  # noqa: F401
from workbench.grade_types import (  # noqa: F401
    AXES, FIXTURES, Hysteresis, NoiseSpec, SensorSpec, SpecError, TRIADS, TriadSpec,
)
from workbench.model import ThermalModel, TriadModel


@dataclass(frozen=True)
class UnitTruth:
    """The true model of one simulated unit (SI), written to ``truth.json``; no analysis reads it.

    ``gyro``/``accel``/``mag`` are the deterministic error models (``mag`` bias = hard iron,
    ``I + M`` = soft iron and axis errors), ``*_noise`` the noise terms, ``*_range`` the
    full scales (rad/s, m/s^2, µT), ``*_hysteresis`` optional thermal bias hysteresis.
    ``thermal_time_constant_s`` is the first-order lag of the unit temperature behind the
    chamber air; ``temp_sensor_noise_c`` the white noise of the unit's own thermometer (°C).
    ``sensing_axes`` maps a triad to its real sensing axes (all three unless the grade says
    otherwise, e.g. the two-axis CVG).
    """

    serial: str
    model: str
    sample_rate_hz: float
    triads: tuple[str, ...]
    gyro: TriadModel
    accel: TriadModel
    gyro_noise: NoiseSpec
    accel_noise: NoiseSpec
    gyro_range: float
    accel_range: float
    mag: TriadModel | None = None
    mag_noise: NoiseSpec | None = None
    mag_range: float | None = None
    thermal_time_constant_s: float = 600.0
    temp_sensor_noise_c: float = 0.0
    gyro_hysteresis: Hysteresis | None = None
    accel_hysteresis: Hysteresis | None = None
    mag_hysteresis: Hysteresis | None = None
    sensing_axes: Mapping[str, tuple[int, ...]] = field(default_factory=dict)

    def model_of(self, triad: str) -> TriadModel | None:
        """Error model of ``triad`` ('gyro', 'accel', 'mag')."""
        return getattr(self, triad)

    def noise_of(self, triad: str) -> NoiseSpec | None:
        """Noise terms of ``triad``."""
        return getattr(self, f"{triad}_noise")

    def range_of(self, triad: str) -> float | None:
        """Full-scale range of ``triad``, SI."""
        return getattr(self, f"{triad}_range")

    def hysteresis_of(self, triad: str) -> Hysteresis | None:
        """Thermal bias hysteresis of ``triad`` (or None)."""
        return getattr(self, f"{triad}_hysteresis")

    def to_dict(self) -> dict:
        """JSON-ready dict (SI units: rad/s, m/s^2, µT, °C, s)."""
        out: dict = {"format": "workbench-truth/1", "serial": self.serial, "model": self.model,
                     "sample_rate_hz": float(self.sample_rate_hz), "triads": list(self.triads),
                     "thermal_time_constant_s": float(self.thermal_time_constant_s),
                     "temp_sensor_noise_c": float(self.temp_sensor_noise_c),
                     "sensing_axes": {k: list(v) for k, v in self.sensing_axes.items()}}
        for triad in self.triads:
            hyst = self.hysteresis_of(triad)
            out[triad] = {"model": _model_to_dict(self.model_of(triad)), "noise": self.noise_of(triad).to_dict(),
                          "range": float(self.range_of(triad)),
                          "hysteresis": None if hyst is None else hyst.to_dict()}
        return out

    @classmethod
    def from_dict(cls, data: Mapping, source: str = "truth.json") -> UnitTruth:
        """Inverse of :meth:`to_dict`; raises :class:`SpecError` naming ``source`` and the field."""
        kwargs: dict = {}
        try:
            triads = tuple(data["triads"])
            for triad in triads:
                d = data[triad]
                kwargs[triad] = _model_from_dict(d["model"])
                kwargs[f"{triad}_noise"] = NoiseSpec(**d["noise"])
                kwargs[f"{triad}_range"] = float(d["range"])
                if d.get("hysteresis"):
                    kwargs[f"{triad}_hysteresis"] = Hysteresis(**d["hysteresis"])
            return cls(serial=str(data["serial"]), model=str(data["model"]),
                       sample_rate_hz=float(data["sample_rate_hz"]), triads=triads,
                       thermal_time_constant_s=float(data["thermal_time_constant_s"]),
                       temp_sensor_noise_c=float(data["temp_sensor_noise_c"]),
                       sensing_axes={k: tuple(v) for k, v in data.get("sensing_axes", {}).items()}, **kwargs)
        except KeyError as exc:
            raise SpecError(f"{source}: missing field {exc.args[0]!r}") from None
        except (CalibrationFormatError, SpecError, TypeError, ValueError) as exc:
            raise SpecError(f"{source}: {exc}") from None


def _model_to_dict(m: TriadModel) -> dict:
    out = {"bias": m.bias.tolist(), "scale_misalignment": m.scale_misalignment.tolist(),
           "nonlinearity": m.nonlinearity.tolist(),
           "g_sensitivity": None if m.g_sensitivity is None else m.g_sensitivity.tolist(), "thermal": None}
    if m.thermal is not None:
        out["thermal"] = {"t_ref_c": m.thermal.t_ref_c, "bias_poly": m.thermal.bias_poly.tolist(),
                          "scale_poly": m.thermal.scale_poly.tolist()}
    return out


def _model_from_dict(d: Mapping) -> TriadModel:
    th = d.get("thermal")
    thermal = None if th is None else ThermalModel(th["t_ref_c"], np.array(th["bias_poly"], float),
                                                   np.array(th["scale_poly"], float))
    return TriadModel(bias=d["bias"], scale_misalignment=d["scale_misalignment"], nonlinearity=d["nonlinearity"],
                      g_sensitivity=d.get("g_sensitivity"), thermal=thermal)

# ---------------------------------------------------------------------------- drawing
def _draw_triad(ts: TriadSpec, t_ref_c: float, rng: np.random.Generator, triad: str) -> TriadModel:
    """One triad's error model: every coefficient = its 1-sigma spread * N(0, 1)."""
    m = np.diag(ts.scale_factor * rng.standard_normal(3))
    off = ts.misalignment[:, None] * rng.standard_normal((3, 3))
    m += off * (1.0 - np.eye(3))
    bias = ts.bias * rng.standard_normal(3)
    nonlin = ts.nonlinearity * rng.standard_normal(3)
    g_sens = None
    if ts.g_sensitivity is not None:
        g_sens = ts.g_sensitivity[:, None] * rng.standard_normal((3, 3))
    thermal = None
    kb, ks = ts.bias_temp_poly.shape[1], ts.scale_temp_poly.shape[1]
    if kb or ks:
        bias_poly = np.zeros((3, kb + 1))
        bias_poly[:, 1:] = ts.bias_temp_poly * rng.standard_normal((3, kb))
        scale_poly = np.zeros((3, ks + 1))
        scale_poly[:, 1:] = ts.scale_temp_poly * rng.standard_normal((3, ks))
        thermal = ThermalModel(t_ref_c, bias_poly, scale_poly)
    try:
        return TriadModel(bias=bias, scale_misalignment=m, nonlinearity=nonlin, g_sensitivity=g_sens,
                          thermal=thermal)
    except CalibrationFormatError as exc:
        raise SpecError(f"{triad}: drawn model invalid ({exc})") from None


def draw_unit(spec: SensorSpec, seed: int, serial: str | None = None) -> UnitTruth:
    """Draw one unit of grade ``spec`` with ``seed`` (a different seed gives a different unit).

    Each triad is drawn from its own child of ``SeedSequence([seed, crc32(grade name)])``,
    so a triad's draw does not depend on which other triads the grade has, and units of two
    grades drawn with one seed are independent. The serial defaults to ``"<grade>-<seed>"``.
    """
    children = np.random.SeedSequence([seed, zlib.crc32(spec.name.encode())]).spawn(len(TRIADS))
    kwargs: dict = {}
    for triad, child in zip(TRIADS, children):
        ts = spec.specs.get(triad)
        if ts is None:
            continue
        kwargs[triad] = _draw_triad(ts, spec.t_ref_c, np.random.default_rng(child), triad)
        kwargs[f"{triad}_noise"] = ts.noise
        kwargs[f"{triad}_range"] = ts.range
        kwargs[f"{triad}_hysteresis"] = ts.hysteresis
    return UnitTruth(serial=serial or f"{spec.name}-{seed}", model=spec.name, sample_rate_hz=spec.sample_rate_hz,
                     triads=spec.triads, thermal_time_constant_s=spec.thermal_time_constant_s,
                     temp_sensor_noise_c=spec.temp_sensor_noise_c,
                     sensing_axes={t: spec.specs[t].sensing_axes for t in spec.triads}, **kwargs)
