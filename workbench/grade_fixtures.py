"""Reading sensor-grade fixtures (``fixtures/units/*.yaml``): lab-unit keys to SI, one-line errors.

:func:`load_spec` (a grade name or a fixture path -> :class:`~workbench.grade_types.SensorSpec`)
and :func:`grade_names`. A YAML key carries its lab unit (``bias_deg_per_h``, ``arw_deg_per_sqrt_h``,
``scale_factor_ppm``, ...; the table of units per physical dimension is here); docs/grades.md
lists the keys.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from workbench.grade_types import AXES, FIXTURES, Hysteresis, NoiseSpec, SensorSpec, SpecError, TRIADS, TriadSpec
from workbench.safe_yaml import load_yaml_file
from workbench.units import factor


# ---------------------------------------------------------------------------- lab units
_QUANTITY = {"gyro": "rate", "accel": "accel", "mag": "field"}
# The YAML spelling of each lab unit per physical dimension -> its name in workbench.units (the
# one unit table: the SI factor comes from units.factor); a YAML key is ``<term>_<unit>``.
_UNITS: dict[str, dict[str, str]] = {
    "rate": {"deg_per_h": "deg/h", "deg_per_s": "deg/s", "rad_per_s": "rad/s"},
    "accel": {"mg": "mg", "ug": "ug", "g": "g", "m_per_s2": "m/s^2", "m_per_s_per_h": "m/s/h"},
    "field": {"ut": "uT", "nt": "nT", "mgauss": "mgauss", "gauss": "gauss"},
    "rate/rthz": {"deg_per_sqrt_h": "deg/sqrt(h)", "deg_per_h_per_sqrt_hz": "deg/h/sqrt(Hz)",
                  "deg_per_s_per_sqrt_hz": "deg/s/sqrt(Hz)", "rad_per_s_per_sqrt_hz": "rad/s/sqrt(Hz)"},
    "accel/rthz": {"ug_per_sqrt_hz": "ug/sqrt(Hz)", "mg_per_sqrt_hz": "mg/sqrt(Hz)", "m_per_s_per_sqrt_h": "m/s/sqrt(h)",
                   "m_per_s2_per_sqrt_hz": "m/s^2/sqrt(Hz)"},
    "field/rthz": {"ut_per_sqrt_hz": "uT/sqrt(Hz)", "nt_per_sqrt_hz": "nT/sqrt(Hz)"},
    "rate/rts": {"deg_per_h_per_sqrt_h": "deg/h/sqrt(h)", "rad_per_s_per_sqrt_s": "rad/s/sqrt(s)"},
    "accel/rts": {"m_per_s_per_h_per_sqrt_h": "m/s/h/sqrt(h)", "ug_per_sqrt_s": "ug/sqrt(s)",
                  "m_per_s2_per_sqrt_s": "m/s^2/sqrt(s)"},
    "field/rts": {"ut_per_sqrt_s": "uT/sqrt(s)"},
    "rate*s": {"rad": "rad", "urad": "urad", "arcsec": "arcsec"},
    "accel*s": {"m_per_s": "m/s", "mm_per_s": "mm/s"},
    "field*s": {"ut_s": "uT*s"},
    "ratio": {"ppm": "ppm", "pct": "%", "mrad": "mrad", "urad": "urad"},
    "fs": {"ppm_fs": "ppm", "pct_fs": "%"},
    "rate/accel": {"deg_per_h_per_g": "deg/h/g", "deg_per_s_per_g": "deg/s/g", "rad_per_s_per_m_per_s2": "rad/s/(m/s^2)"},
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
    if not str(name_or_path).strip():  # resolved, a blank name was '.../fixtures/units/.yaml'
        raise SpecError(f"empty grade name (known grades: {', '.join(grade_names())})")
    path = _resolve(name_or_path)
    if not path.is_file():
        known = ", ".join(grade_names())
        raise SpecError(f"{path}: no such sensor-grade file (known grades: {known})")
    data = load_yaml_file(path, error=SpecError)  # size and alias expansion limited, the line named
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
        return canonical, factor(table[unit])
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
        "temp_sensor_noise_c", "imperfections", *TRIADS}
# keys of a triad in the ``imperfections`` block: field -> dimension template ('q' = the triad's quantity)
_IMPERFECTION_TERMS = {"warm_up_bias": "q", "turn_on_bias": "q", "turn_on_scale": "ratio",
                       "scale_drift": "ratio/h", "noise_temp_coeff": "1/C"}
_IMPERFECTION_UNITS = {"ratio/h": {"ppm_per_h": "ppm/h", "pct_per_h": "%/h"},
                       "1/C": {"per_c": "1/degC", "pct_per_c": "%/degC"}}
_IMPERFECTION_TOP = {"warm_up_tau_s", "noise_t_ref_c", "notes", *TRIADS}


def _parse_imperfections(data, triads: tuple[str, ...], path: Path) -> dict:
    """The grade's ``imperfections`` block (lab-unit keys such as ``turn_on_bias_mg``) -> SI
    (see :class:`~workbench.grade_types.SensorSpec`); one-line SpecError naming the field."""
    where = f"{path}: imperfections"
    if not isinstance(data, Mapping):
        raise SpecError(f"{where}: expected a mapping (warm_up_tau_s, noise_t_ref_c, notes, and per triad)")
    unknown = sorted(set(map(str, data)) - _IMPERFECTION_TOP)
    if unknown:
        raise SpecError(f"{where}: unknown field {unknown[0]!r} (fields: {', '.join(sorted(_IMPERFECTION_TOP))})")
    out: dict = {}
    for key in ("warm_up_tau_s", "noise_t_ref_c"):
        if key in data:
            out[key] = _number(data[key], f"{where}.{key}", positive=key == "warm_up_tau_s")
    for triad in TRIADS:
        if triad not in data:
            continue
        if triad not in triads:
            raise SpecError(f"{where}.{triad}: the grade has no {triad} triad")
        block = data[triad]
        if not isinstance(block, Mapping):
            raise SpecError(f"{where}.{triad}: expected a mapping of imperfections")
        values: dict = {}
        for key, raw in block.items():
            at = f"{where}.{triad}.{key}"
            term = next((t for t in _IMPERFECTION_TERMS if str(key).startswith(t + "_")), None)
            if term is None:
                raise SpecError(f"{at}: unknown key (terms: {', '.join(_IMPERFECTION_TERMS)})")
            dim = _IMPERFECTION_TERMS[term].replace("q", _QUANTITY[triad])
            table = _UNITS.get(dim) or _IMPERFECTION_UNITS[dim]
            unit = str(key)[len(term) + 1:]
            if unit not in table:
                raise SpecError(f"{at}: unit {unit!r} is not one of: {', '.join(table)}")
            if term == "warm_up_bias":  # a transient with its sign, not a spread
                items = raw if isinstance(raw, list) else [raw]
                if len(items) not in (1, 3):
                    raise SpecError(f"{at}: expected a number or a list of 3 (x, y, z), got {len(items)} values")
                values[term] = np.broadcast_to([_number(v, at) for v in items], (3,)) * factor(table[unit])
            else:
                values[term] = _axis_values(raw, at) * factor(table[unit])
        out[triad] = values
    return out


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
        specs=specs, path=path,
        imperfections=_parse_imperfections(data["imperfections"], triads, path) if "imperfections" in data else {})
