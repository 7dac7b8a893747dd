"""Calibration sets: the product of the workbench.

A :class:`CalibrationSet` is an immutable record of per-triad error models
(:class:`workbench.model.TriadModel`), their 1-sigma uncertainties, noise terms with 95 %
intervals, and provenance. JSON is the canonical file format (``workbench-calibration/1``),
validated against ``workbench/schema/calibration.schema.json`` on every read and write.
Merging partial sets of one unit is :mod:`workbench.calset_merge` (:func:`merge` here calls it).

Uncertainty arrays use NaN internally (``null`` in JSON) for "not observed by the data":
the coefficient then holds its prior value (zero) and must not be trusted as an estimate.
"""

from __future__ import annotations

import copy
import hashlib
import json
import uuid
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from functools import lru_cache
from importlib import resources
from pathlib import Path

import jsonschema
import numpy as np

from workbench import __version__
from workbench.confine import name_problems
from workbench.errors import CalibrationFormatError
from workbench.files import atomic_write_text, file_sha256  # noqa: F401  (re-exported: older imports)
from workbench.json_values import json_default, json_value
from workbench.model import COEFFICIENT_FIELDS, ThermalModel, TriadModel
from workbench.values import Unit

FORMAT = "workbench-calibration/1"
FORMAT_FAMILY = "workbench-calibration/"
TRIADS = ("gyro", "accel", "mag")
NOISE_TERMS = {
    "gyro": ("arw", "bias_instability", "rrw", "quantization", "rate_ramp"),
    "accel": ("vrw", "bias_instability", "rrw", "quantization", "rate_ramp"),
}
_SHAPES = {"bias": (3,), "scale_misalignment": (3, 3), "nonlinearity": (3,), "g_sensitivity": (3, 3)}


@lru_cache(maxsize=1)
def schema() -> dict:
    """The JSON Schema of the calibration-set format (a dict)."""
    text = resources.files("workbench").joinpath("schema/calibration.schema.json").read_text()
    return json.loads(text)


@dataclass(frozen=True)
class TriadCalibration:
    """A triad's error model plus its 1-sigma uncertainties.

    ``sigma`` maps a field name (``bias``, ``scale_misalignment``, ``nonlinearity``,
    ``g_sensitivity``, ``thermal.bias_poly``, ``thermal.scale_poly``) to an array of the
    field's shape; NaN marks an element the data did not observe. A missing key means
    no uncertainty was estimated for that field (treated as not observed).
    For a magnetometer, ``bias`` is the hard iron (µT), ``I + M`` the soft-iron distortion
    and ``field_norm_ut`` the fitted field magnitude.
    """

    model: TriadModel
    sigma: Mapping[str, np.ndarray] = field(default_factory=dict)
    field_norm_ut: float | None = None
    field_norm_ut_sigma: float | None = None
    thermal_range_c: tuple[float, float] | None = None

    def sigma_of(self, name: str) -> np.ndarray:
        """Uncertainty array of field ``name`` (NaN where not observed)."""
        if name in self.sigma:
            return np.asarray(self.sigma[name], float)
        if name.startswith("thermal."):
            th = self.model.thermal
            shape = getattr(th, name.split(".")[1]).shape if th is not None else (3, 0)
        else:
            shape = _SHAPES[name]
        return np.full(shape, np.nan)


@dataclass(frozen=True)
class Provenance:
    """Where a set came from: procedures, sessions (id, procedure, SHA-256 of samples), software."""

    procedures: tuple[str, ...] = ()
    sessions: tuple[Mapping, ...] = ()
    software_version: str = __version__
    merged_from: tuple[str, ...] = ()


def _now() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


@dataclass(frozen=True)
class CalibrationSet:
    """An immutable calibration set (see the module docstring)."""

    unit: Unit
    triads: Mapping[str, TriadCalibration] = field(default_factory=dict)
    noise: Mapping[str, Mapping[str, list]] = field(default_factory=dict)
    provenance: Provenance = field(default_factory=Provenance)
    notes: Mapping[str, object] = field(default_factory=dict)
    id: str = field(default_factory=lambda: str(uuid.uuid4()))
    created: str = field(default_factory=_now)

    def __post_init__(self) -> None:
        for name in self.triads:
            if name not in TRIADS:
                raise CalibrationFormatError(f"unknown triad {name!r} (expected one of {', '.join(TRIADS)})")
        for name in self.noise:
            if name not in NOISE_TERMS:
                raise CalibrationFormatError(f"noise.{name}: unknown triad for noise terms")

    # -- access ---------------------------------------------------------------------
    def model(self, triad: str) -> TriadModel:
        """The :class:`TriadModel` of ``triad``; raises if the set has no such triad."""
        if triad not in self.triads:
            raise CalibrationFormatError(f"set {self.id}: no {triad} triad")
        return self.triads[triad].model

    def noise_term(self, triad: str, term: str) -> np.ndarray:
        """Noise term (3,) SI for ``triad`` (NaN per axis where not observed or absent)."""
        values = self.noise.get(triad, {}).get(term)
        if values is None:
            return np.full(3, np.nan)
        return np.array([np.nan if v is None else v for v in values], float)

    # -- JSON ----------------------------------------------------------------------
    def to_dict(self) -> dict:
        """The canonical JSON-ready dict (validated)."""
        out: dict = {
            "format": FORMAT,
            "id": self.id,
            "unit": {"serial": self.unit.serial, "model": self.unit.model},
            "created": self.created,
            "provenance": {
                "procedures": list(self.provenance.procedures),
                "sessions": [dict(s) for s in self.provenance.sessions],
                "software_version": self.provenance.software_version,
            },
        }
        if self.provenance.merged_from:
            out["provenance"]["merged_from"] = list(self.provenance.merged_from)
        for name in TRIADS:
            if name in self.triads:
                out[name] = _triad_to_dict(name, self.triads[name])
        if self.noise:
            out["noise"] = copy.deepcopy({k: dict(v) for k, v in self.noise.items()})
        if self.notes:
            out["notes"] = json.loads(json.dumps(self.notes, default=json_default))
        validate(out, source=f"set {self.id}")
        return out

    def to_json(self) -> str:
        """Canonical JSON text (indented, keys in a stable order)."""
        return json.dumps(self.to_dict(), indent=2) + "\n"

    def sha256(self) -> str:
        """SHA-256 of the canonical JSON text."""
        return hashlib.sha256(self.to_json().encode()).hexdigest()

    def save(self, path: str | Path) -> Path:
        """Write the set atomically to ``path`` (a temp file renamed into place)."""
        return atomic_write_text(Path(path), self.to_json())

    def name_problems(self, source: str | None = None) -> list[str]:
        """The id / serial / model rules this set breaks (:func:`name_problems`); empty for a set that
        could be written today."""
        return name_problems(self.id, self.unit.serial, self.unit.model, source or f"set {self.id}")

    @classmethod
    def from_dict(cls, data: Mapping, source: str = "<dict>", names: bool = True) -> CalibrationSet:
        """Build a set from its JSON dict, validating it; ``source`` names it in errors. ``names=False``
        reads a set stored before the id / serial / model rules (:meth:`name_problems` says which it
        breaks); writing or exporting it is still refused."""
        validate(data, source=source, names=names)
        triads = {name: _triad_from_dict(name, data[name], source) for name in TRIADS if name in data}
        prov = data["provenance"]
        return cls(
            unit=Unit(data["unit"]["serial"], data["unit"].get("model", "")),
            triads=triads,
            noise=data.get("noise", {}),
            provenance=Provenance(
                procedures=tuple(prov["procedures"]),
                sessions=tuple(prov["sessions"]),
                software_version=prov["software_version"],
                merged_from=tuple(prov.get("merged_from", ())),
            ),
            notes=data.get("notes", {}),
            id=data["id"],
            created=data["created"],
        )

    @classmethod
    def from_json(cls, text: str, source: str = "<json>", names: bool = True) -> CalibrationSet:
        """Parse and validate JSON text (``names`` as for :meth:`from_dict`)."""
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise CalibrationFormatError(f"{source}: not valid JSON (line {exc.lineno}: {exc.msg})") from None
        return cls.from_dict(data, source=source, names=names)

    @classmethod
    def load(cls, path: str | Path) -> CalibrationSet:
        """Read and validate a calibration file: canonical JSON, or its YAML form (``.yaml`` / ``.yml``,
        as written by ``workbench sets export --format yaml``)."""
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise CalibrationFormatError(f"{path}: cannot read ({exc.strerror})") from None
        except UnicodeDecodeError as exc:
            raise CalibrationFormatError(f"{path}: not UTF-8 text (byte {exc.start})") from None
        if path.suffix.lower() in (".yaml", ".yml"):
            return cls.from_yaml(text, source=str(path))
        return cls.from_json(text, source=str(path))

    @classmethod
    def from_yaml(cls, text: str, source: str = "<yaml>") -> CalibrationSet:
        """Parse and validate the YAML form of a set (the canonical dict; aliases refused)."""
        import yaml

        class _NoAliases(yaml.SafeLoader):
            def compose_node(self, parent, index):  # an alias could expand a small file into a huge one
                if self.check_event(yaml.AliasEvent):
                    raise CalibrationFormatError(f"{source}: YAML aliases are not accepted in a calibration set")
                return super().compose_node(parent, index)

        try:
            data = yaml.load(text, Loader=_NoAliases)  # noqa: S506 - a SafeLoader subclass
        except yaml.YAMLError as exc:
            mark = getattr(exc, "problem_mark", None)
            where = f" (line {mark.line + 1})" if mark is not None else ""
            raise CalibrationFormatError(f"{source}: not valid YAML{where}") from None
        if not isinstance(data, Mapping):
            raise CalibrationFormatError(f"{source}: expected a calibration set mapping, got {type(data).__name__}")
        return cls.from_dict(data, source=source)

    # -- derivation ----------------------------------------------------------------
    def with_provenance(self, procedures=(), sessions=()) -> CalibrationSet:
        """A copy with provenance extended (new id and creation time)."""
        prov = replace(
            self.provenance,
            procedures=tuple(dict.fromkeys((*self.provenance.procedures, *procedures))),
            sessions=(*self.provenance.sessions, *sessions),
        )
        return replace(self, provenance=prov, id=str(uuid.uuid4()), created=_now())


def _none_to_nan(values) -> np.ndarray:
    return np.array(json.loads(json.dumps(values).replace("null", "NaN")), float)


def _triad_to_dict(name: str, tc: TriadCalibration) -> dict:
    m = tc.model
    out: dict = {}
    for f in COEFFICIENT_FIELDS:
        value = getattr(m, f)
        if value is None or (f == "nonlinearity" and not np.any(value) and f not in tc.sigma):
            continue
        if name == "mag" and f in ("nonlinearity", "g_sensitivity"):
            continue
        out[f] = value.tolist()
        out[f + "_sigma"] = json_value(tc.sigma_of(f))
    if m.thermal is not None:
        th = {"t_ref_c": m.thermal.t_ref_c, "bias_poly": m.thermal.bias_poly.tolist(),
              "scale_poly": m.thermal.scale_poly.tolist(),
              "bias_poly_sigma": json_value(tc.sigma_of("thermal.bias_poly")),
              "scale_poly_sigma": json_value(tc.sigma_of("thermal.scale_poly"))}
        if tc.thermal_range_c is not None:
            th["t_min_c"], th["t_max_c"] = map(float, tc.thermal_range_c)
        out["thermal"] = th
    if name == "mag":
        if tc.field_norm_ut is None:
            raise CalibrationFormatError("mag.field_norm_ut: required for a magnetometer triad")
        out["field_norm_ut"] = float(tc.field_norm_ut)
        out["field_norm_ut_sigma"] = (None if tc.field_norm_ut_sigma is None or not np.isfinite(tc.field_norm_ut_sigma)
                                      else float(tc.field_norm_ut_sigma))
    return out


def _triad_from_dict(name: str, d: Mapping, source: str) -> TriadCalibration:
    try:
        thermal = None
        sigma: dict[str, np.ndarray] = {}
        if "thermal" in d:
            th = d["thermal"]
            thermal = ThermalModel(th["t_ref_c"], np.array(th["bias_poly"], float), np.array(th["scale_poly"], float))
            for key in ("bias_poly", "scale_poly"):
                if key + "_sigma" in th:
                    sigma["thermal." + key] = _none_to_nan(th[key + "_sigma"])
        model = TriadModel(
            bias=d["bias"],
            scale_misalignment=d["scale_misalignment"],
            nonlinearity=d.get("nonlinearity", [0.0, 0.0, 0.0]),
            g_sensitivity=d.get("g_sensitivity"),
            thermal=thermal,
        )
    except CalibrationFormatError as exc:
        raise CalibrationFormatError(f"{source}: {name}.{exc}") from None
    for f in COEFFICIENT_FIELDS:
        if f + "_sigma" in d:
            sigma[f] = _none_to_nan(d[f + "_sigma"])
    th = d.get("thermal", {})
    trange = (th["t_min_c"], th["t_max_c"]) if "t_min_c" in th and "t_max_c" in th else None
    return TriadCalibration(model, sigma, d.get("field_norm_ut"), d.get("field_norm_ut_sigma"), trange)


def _check_finite(data, path: str, source: str) -> None:
    if isinstance(data, Mapping):
        for k, v in data.items():
            _check_finite(v, f"{path}.{k}" if path else str(k), source)
    elif isinstance(data, list):
        for i, v in enumerate(data):
            _check_finite(v, f"{path}[{i}]", source)
    elif isinstance(data, float) and not np.isfinite(data):
        raise CalibrationFormatError(f"{source}: {path}: NaN or infinite value")


def validate(data: Mapping, source: str = "<dict>", names: bool = True) -> None:
    """Validate a calibration dict against the schema; raise a one-line error naming the field.

    ``names=False`` leaves out the id / serial / model rules (:func:`name_problems`), to read a set
    stored before them."""
    if not isinstance(data, Mapping):
        raise CalibrationFormatError(f"{source}: top level must be a JSON object")
    fmt = data.get("format")
    if isinstance(fmt, str) and fmt.startswith(FORMAT_FAMILY) and fmt != FORMAT:
        raise CalibrationFormatError(
            f"{source}: format {fmt!r} is not supported by this version ({FORMAT}); "
            "convert the file with the workbench version that wrote it")
    for name in data:
        if name in ("gyros", "accels", "magnetometer", "acc", "gyr") or (
                name not in schema()["properties"] and isinstance(data.get(name), Mapping) and "bias" in data[name]):
            raise CalibrationFormatError(f"{source}: unknown triad {name!r} (expected one of {', '.join(TRIADS)})")
    _check_finite(data, "", source)
    errors = sorted(jsonschema.Draft202012Validator(schema()).iter_errors(data), key=lambda e: list(e.path))
    if errors:
        err = errors[0]
        where = ".".join(str(p) for p in err.absolute_path) or "(top level)"
        raise CalibrationFormatError(f"{source}: {where}: {err.message[:200]}")
    problems = name_problems(data["id"], data["unit"]["serial"], data["unit"]["model"], source) if names else []
    if problems:
        raise CalibrationFormatError(problems[0])


def merge(*sets: CalibrationSet) -> CalibrationSet:
    """Merge partial sets of one unit into one: :func:`workbench.calset_merge.merge` (the best-determined
    coefficient element by element, the latest thermal block and noise terms, the union of provenance)."""
    from workbench.calset_merge import merge as merge_sets

    return merge_sets(*sets)
