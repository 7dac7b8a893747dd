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
from pathlib import Path

import numpy as np
import yaml

from workbench.errors import CalibrationFormatError, WorkbenchError
from workbench.model import ThermalModel, TriadModel
from workbench.units import DEG, G0, HOUR

FIXTURES = Path(__file__).parents[1] / "fixtures" / "units"
TRIADS = ("gyro", "accel", "mag")
AXES = ("x", "y", "z")


class SpecError(WorkbenchError):
    """A sensor-grade fixture (or a unit truth) is malformed: names the file and field."""


# ---------------------------------------------------------------------------- lab units
_RT_H = np.sqrt(HOUR)
_QUANTITY = {"gyro": "rate", "accel": "accel", "mag": "field"}
# SI value of one lab unit, per physical dimension; a YAML key is ``<term>_<unit>``.
_UNITS: dict[str, dict[str, float]] = {
    "rate": {"deg_per_h": DEG / HOUR, "deg_per_s": DEG, "rad_per_s": 1.0},
    "accel": {"mg": G0 * 1e-3, "ug": G0 * 1e-6, "g": G0, "m_per_s2": 1.0, "m_per_s_per_h": 1.0 / HOUR},
    "field": {"ut": 1.0, "nt": 1e-3, "mgauss": 0.1, "gauss": 100.0},
    "rate/rthz": {"deg_per_sqrt_h": DEG / _RT_H, "deg_per_h_per_sqrt_hz": DEG / HOUR,
                  "deg_per_s_per_sqrt_hz": DEG, "rad_per_s_per_sqrt_hz": 1.0},
    "accel/rthz": {"ug_per_sqrt_hz": G0 * 1e-6, "mg_per_sqrt_hz": G0 * 1e-3, "m_per_s_per_sqrt_h": 1.0 / _RT_H,
                   "m_per_s2_per_sqrt_hz": 1.0},
    "field/rthz": {"ut_per_sqrt_hz": 1.0, "nt_per_sqrt_hz": 1e-3},
    "rate/rts": {"deg_per_h_per_sqrt_h": DEG / HOUR / _RT_H, "rad_per_s_per_sqrt_s": 1.0},
    "accel/rts": {"m_per_s_per_h_per_sqrt_h": 1.0 / HOUR / _RT_H, "ug_per_sqrt_s": G0 * 1e-6,
                  "m_per_s2_per_sqrt_s": 1.0},
    "field/rts": {"ut_per_sqrt_s": 1.0},
    "rate*s": {"rad": 1.0, "urad": 1e-6, "arcsec": DEG / 3600.0},
    "accel*s": {"m_per_s": 1.0, "mm_per_s": 1e-3},
    "field*s": {"ut_s": 1.0},
    "ratio": {"ppm": 1e-6, "pct": 1e-2, "mrad": 1e-3, "urad": 1e-6},
    "fs": {"ppm_fs": 1e-6, "pct_fs": 1e-2},
    "rate/accel": {"deg_per_h_per_g": DEG / HOUR / G0, "deg_per_s_per_g": DEG / G0, "rad_per_s_per_m_per_s2": 1.0},
}
_DIM_LABEL = {
    "rate": "angular-rate", "accel": "acceleration", "field": "magnetic-field",
    "rate/rthz": "rate noise density", "accel/rthz": "acceleration noise density",
    "field/rthz": "field noise density", "rate/rts": "rate random walk", "accel/rts": "acceleration random walk",
    "field/rts": "field random walk", "rate*s": "angle", "accel*s": "velocity", "field*s": "field x time",
    "ratio": "dimensionless", "fs": "fraction-of-full-scale", "rate/accel": "rate per acceleration",
}
# term -> dimension template ('q' = the triad's quantity); noise aliases map to 'white'
_TERMS = {
    "range": "q", "bias": "q", "bias_instability": "q", "resolution": "q", "bias_hysteresis": "q",
    "bias_temp_poly": "q", "white": "q/rthz", "rrw": "q/rts", "quantization": "q*s",
    "scale_factor": "ratio", "misalignment": "ratio", "scale_temp_poly": "ratio",
    "nonlinearity": "fs", "g_sensitivity": "rate/accel",
}
_ALIASES = {"arw": "white", "vrw": "white", "noise": "white"}
_PLAIN = {"hysteresis_width_c", "sensing_axes"}  # triad keys without a lab unit


# ---------------------------------------------------------------------------- dataclasses
def _vec3(value, name: str) -> np.ndarray:
    arr = np.broadcast_to(np.asarray(value, float), (3,)).copy()
    if not np.all(np.isfinite(arr)):
        raise SpecError(f"{name}: NaN or infinite value")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class NoiseSpec:
    """Noise terms of one triad, per axis, SI (u = rad/s, m/s^2 or µT).

    Attributes
    ----------
    white : (3,) white-noise density, u/√Hz (gyro: ARW in rad/√s; accel: VRW in m/s/√s)
    bias_instability : (3,) B, u: flicker floor as in IEEE 952, minimum ADEV = 0.664 B
    rrw : (3,) rate random walk K, u/√s (u/s/√Hz): ADEV = K √(τ/3)
    quantization : (3,) IEEE 952 Q of the integrated output, u·s (rad, m/s, µT·s): ADEV = √3 Q / τ
    resolution : (3,) output LSB, u (rounding of each sample; 0 = none)
    """

    white: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bias_instability: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rrw: np.ndarray = field(default_factory=lambda: np.zeros(3))
    quantization: np.ndarray = field(default_factory=lambda: np.zeros(3))
    resolution: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        for name in ("white", "bias_instability", "rrw", "quantization", "resolution"):
            arr = _vec3(getattr(self, name), name)
            if np.any(arr < 0):
                raise SpecError(f"{name}: negative noise term")
            object.__setattr__(self, name, arr)

    def to_dict(self) -> dict:
        """JSON-ready dict (lists, SI)."""
        return {k: getattr(self, k).tolist() for k in ("white", "bias_instability", "rrw", "quantization",
                                                        "resolution")}


@dataclass(frozen=True)
class Hysteresis:
    """Thermal hysteresis of a triad's bias (a play operator on the unit temperature).

    The bias gains ``gap / 2 * s`` with ``s = (T - p) / width_c`` in [-1, 1], where the play
    point ``p`` follows ``T`` lagging by at most ``width_c``: ``p_k = clip(p_{k-1}, T_k - w,
    T_k + w)``, starting at ``p_0 = T_0`` (s = 0). After warming by more than ``width_c``
    the bias sits on the upper branch (+gap/2) and stays there while the temperature holds;
    after cooling by more than ``width_c`` on the lower branch (-gap/2). ``gap`` is the
    warming-minus-cooling bias difference at the same temperature, (3,) u.
    """

    gap: np.ndarray
    width_c: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "gap", _vec3(self.gap, "bias_hysteresis"))
        if not (np.isfinite(self.width_c) and self.width_c > 0):
            raise SpecError(f"hysteresis_width_c: must be a positive temperature span, got {self.width_c}")

    def to_dict(self) -> dict:
        """JSON-ready dict (SI; width in °C)."""
        return {"gap": self.gap.tolist(), "width_c": float(self.width_c)}


@dataclass(frozen=True)
class TriadSpec:
    """One triad of a grade, SI: 1-sigma spreads of the deterministic errors, noise, range.

    Attributes
    ----------
    range : full-scale input, u (outputs saturate at ±range)
    bias, scale_factor, nonlinearity : (3,) sigma per axis (u; -; 1/u)
    misalignment : (3,) sigma of each off-diagonal element of M in row i (rad)
    g_sensitivity : (3,) sigma of each element of G in row i (rad/s per m/s^2), or None
    bias_temp_poly : (3, K) sigma of the bias coefficient of (T - t_ref)^(k+1), u/°C^(k+1)
    scale_temp_poly : (3, K) sigma of the scale-factor coefficient of (T - t_ref)^(k+1), 1/°C^(k+1)
    noise : NoiseSpec (the grade's values, not spreads)
    hysteresis : Hysteresis or None (fixed values, not spreads)
    sensing_axes : indices of the axes that are real sensing axes (see docs/grades.md)
    """

    range: float
    bias: np.ndarray
    scale_factor: np.ndarray
    misalignment: np.ndarray
    nonlinearity: np.ndarray
    g_sensitivity: np.ndarray | None
    bias_temp_poly: np.ndarray
    scale_temp_poly: np.ndarray
    noise: NoiseSpec
    hysteresis: Hysteresis | None = None
    sensing_axes: tuple[int, ...] = (0, 1, 2)


@dataclass(frozen=True)
class SensorSpec:
    """A sensor grade loaded from a fixture, SI inside (see :func:`load_spec`)."""

    name: str
    description: str
    source: str
    notes: str
    sample_rate_hz: float
    triads: tuple[str, ...]
    t_ref_c: float
    thermal_time_constant_s: float
    temp_sensor_noise_c: float
    specs: Mapping[str, TriadSpec]
    path: Path | None = None

    @property
    def gyro(self) -> TriadSpec | None:
        """Gyro triad spec (or None)."""
        return self.specs.get("gyro")

    @property
    def accel(self) -> TriadSpec | None:
        """Accelerometer triad spec (or None)."""
        return self.specs.get("accel")

    @property
    def mag(self) -> TriadSpec | None:
        """Magnetometer triad spec (or None)."""
        return self.specs.get("mag")


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


# ---------------------------------------------------------------------------- loading
def _resolve(name_or_path: str | Path) -> Path:
    """A grade name -> its fixture; a bare file name not found here -> the fixtures folder."""
    candidate = Path(name_or_path)
    if candidate.parent != Path(".") or candidate.is_file():
        return candidate
    return FIXTURES / (candidate.name if candidate.suffix in (".yaml", ".yml") else f"{candidate.name}.yaml")


def grade_names() -> list[str]:
    """Names of the grades shipped in ``fixtures/units``."""
    return sorted(p.stem for p in FIXTURES.glob("*.yaml"))


def load_spec(name_or_path: str | Path) -> SensorSpec:
    """Load a grade: a name (``"industrial_mems"`` -> ``fixtures/units/industrial_mems.yaml``)
    or a path to a YAML file. Lab units in the keys are converted to SI.

    Raises :class:`SpecError` naming the file and the field for a missing file, bad YAML,
    an unknown key or unit, a wrong shape or a non-physical value.
    """
    path = _resolve(name_or_path)
    if not path.is_file():
        known = ", ".join(grade_names())
        raise SpecError(f"{path}: no such sensor-grade file (known grades: {known})")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        where = getattr(exc, "problem_mark", None)
        line = f" line {where.line + 1}" if where is not None else ""
        raise SpecError(f"{path}:{line} invalid YAML ({getattr(exc, 'problem', exc)})") from None
    if not isinstance(data, Mapping):
        raise SpecError(f"{path}: expected a mapping of grade fields at the top level")
    return _parse_spec(data, path)


def _number(value, where: str, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise SpecError(f"{where}: expected a number, got {value!r}")
    if positive and value <= 0:
        raise SpecError(f"{where}: must be positive, got {value!r}")
    return float(value)


def _axis_values(value, where: str) -> np.ndarray:
    """A scalar (all axes) or a list of 3 numbers -> (3,), non-negative."""
    items = value if isinstance(value, list) else [value]
    if len(items) not in (1, 3):
        raise SpecError(f"{where}: expected a number or a list of 3 (x, y, z), got {len(items)} values")
    arr = np.array([_number(v, where) for v in items])
    if np.any(arr < 0):
        raise SpecError(f"{where}: a 1-sigma spread or noise term cannot be negative")
    return np.broadcast_to(arr, (3,)).copy()


def _poly_values(value, where: str) -> np.ndarray:
    """A list over powers 1..K, each a number or a list of 3 -> (3, K)."""
    if not isinstance(value, list) or not value:
        raise SpecError(f"{where}: expected a list of coefficients for powers 1, 2, ... of (T - t_ref_c)")
    return np.stack([_axis_values(v, f"{where}[{k}]") for k, v in enumerate(value)], axis=1)


def _split_key(key: str, triad: str, where: str) -> tuple[str, float]:
    """``'bias_deg_per_h'`` -> ('bias', SI factor), checking the unit's dimension."""
    quantity = _QUANTITY[triad]
    for term in sorted({*_TERMS, *_ALIASES}, key=len, reverse=True):
        if not key.startswith(term + "_"):
            continue
        unit = key[len(term) + 1:]
        canonical = _ALIASES.get(term, term)
        dim = _TERMS[canonical].replace("q", quantity)
        table = _UNITS[dim]
        if unit not in table:
            raise SpecError(f"{where}: unit {unit!r} is not a {_DIM_LABEL[dim]} unit for {canonical} "
                            f"(use one of: {', '.join(table)})")
        return canonical, table[unit]
    raise SpecError(f"{where}: unknown key (terms: {', '.join(sorted({*_TERMS, *_ALIASES, *_PLAIN}))})")


def _parse_triad(data, triad: str, path: Path) -> TriadSpec:
    if not isinstance(data, Mapping):
        raise SpecError(f"{path}: {triad}: expected a mapping of error terms")
    values: dict[str, np.ndarray | float] = {}
    for key, raw in data.items():
        where = f"{path}: {triad}.{key}"
        if key in _PLAIN:
            continue
        term, factor = _split_key(str(key), triad, where)
        if term in values:
            raise SpecError(f"{where}: {term} given twice")
        if term == "range":
            values[term] = _number(raw, where, positive=True) * factor
        elif term.endswith("temp_poly"):
            values[term] = _poly_values(raw, where) * factor
        else:
            values[term] = _axis_values(raw, where) * factor
    if "range" not in values:
        raise SpecError(f"{path}: {triad}: missing range (e.g. range_deg_per_s, range_g, range_ut)")
    full_scale = values["range"]
    noise = NoiseSpec(**{k: values.get(k, np.zeros(3)) for k in ("white", "bias_instability", "rrw",
                                                                 "quantization", "resolution")})
    hysteresis = None
    if "bias_hysteresis" in values:
        if "hysteresis_width_c" not in data:
            raise SpecError(f"{path}: {triad}.hysteresis_width_c: required with bias_hysteresis")
        hysteresis = Hysteresis(values["bias_hysteresis"],
                                _number(data["hysteresis_width_c"], f"{path}: {triad}.hysteresis_width_c", True))
    axes = data.get("sensing_axes", list(AXES))
    if not isinstance(axes, list) or not axes or any(a not in AXES for a in axes):
        raise SpecError(f"{path}: {triad}.sensing_axes: expected a list of x, y, z, got {axes!r}")
    if "g_sensitivity" in values and triad != "gyro":
        raise SpecError(f"{path}: {triad}.g_sensitivity: only a gyro has g-sensitivity")
    return TriadSpec(
        range=full_scale,
        bias=values.get("bias", np.zeros(3)),
        scale_factor=values.get("scale_factor", np.zeros(3)),
        misalignment=values.get("misalignment", np.zeros(3)),
        nonlinearity=values.get("nonlinearity", np.zeros(3)) / full_scale,
        g_sensitivity=values.get("g_sensitivity"),
        bias_temp_poly=values.get("bias_temp_poly", np.zeros((3, 0))),
        scale_temp_poly=values.get("scale_temp_poly", np.zeros((3, 0))),
        noise=noise, hysteresis=hysteresis, sensing_axes=tuple(AXES.index(a) for a in axes))


_TOP = {"name", "description", "source", "notes", "sample_rate_hz", "t_ref_c", "thermal_time_constant_s",
        "temp_sensor_noise_c", *TRIADS}


def _parse_spec(data: Mapping, path: Path) -> SensorSpec:
    unknown = sorted(set(map(str, data)) - _TOP)
    if unknown:
        raise SpecError(f"{path}: unknown field {unknown[0]!r} (fields: {', '.join(sorted(_TOP))})")
    for key in ("name", "sample_rate_hz", "gyro", "accel"):
        if key not in data:
            raise SpecError(f"{path}: missing field {key!r}")
    triads = tuple(t for t in TRIADS if t in data)
    specs = {t: _parse_triad(data[t], t, path) for t in triads}
    return SensorSpec(
        name=str(data["name"]), description=str(data.get("description", "")), source=str(data.get("source", "")),
        notes=str(data.get("notes", "")).strip(),
        sample_rate_hz=_number(data["sample_rate_hz"], f"{path}: sample_rate_hz", positive=True),
        triads=triads,
        t_ref_c=_number(data.get("t_ref_c", 25.0), f"{path}: t_ref_c"),
        thermal_time_constant_s=_number(data.get("thermal_time_constant_s", 600.0),
                                        f"{path}: thermal_time_constant_s", positive=True),
        temp_sensor_noise_c=_number(data.get("temp_sensor_noise_c", 0.0), f"{path}: temp_sensor_noise_c"),
        specs=specs, path=path)


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
