"""Import profiles (YAML, ``format: workbench-import/1``) read and checked before any data is read.

Every key is checked for its type, unit and range here, so that applying the profile cannot
fail halfway on a malformed profile: an error names the profile file and the key path
(``streams.mag.columns.mx.unit``). A profile has either ``columns`` (one file, given on the
command line) or ``streams`` (one file per stream inside the data folder, each with its own
``time`` and ``columns``) and then a ``time_base``. See ``docs/formats.md``.

Public: :func:`load_profile`, :func:`stream_specs`, :data:`PROFILE_FORMAT`.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from workbench.confine import plain_line, safe_component
from workbench.errors import ImportProfileError, RigLimitError
from workbench.importers.readers import READER_KEYS, READER_TYPES, REQUIRED_KEYS
from workbench.importers.streams import SI_UNIT, TIME_UNITS, TRIAD_OF
from workbench.safe_yaml import load_yaml_file
from workbench.sequence import mount_matrix
from workbench.session import ACCEL, GYRO, STEP_KINDS

PROFILE_FORMAT = "workbench-import/1"
_DIMENSION = {"rad/s": {"rad/s", "deg/s", "deg/h"}, "m/s^2": {"m/s^2", "g", "mg", "ug"},
              "uT": {"uT", "ut", "nT", "gauss", "mgauss", "T"}, "rad": {"rad", "deg", "mrad"}, "degC": {"degC"}}
SINGLE = "data"  # the stream name of a single-file profile
# the keys each mapping may hold: a misspelt key (sampel_rate_hz, scael) is refused, never ignored
TOP_KEYS = {"format", "name", "reader", "sample_rate_hz", "time", "columns", "streams", "time_base", "unit", "site",
            "sections", "procedure", "rig"}
COLUMN_KEYS = {"column", "unit", "scale", "offset"}
STREAM_KEYS = {"file", "time", "rate_hz", "range", "repeats", "columns", "reader"}
UNIT_KEYS = {"serial", "model"}
SITE_KEYS = {"latitude_deg", "longitude_deg", "height_m", "table_zero_azimuth_deg", "field_norm_ut"}
SECTIONS_KEYS = {"file", "inline", "steps"}


def _number(value, where: str, lo: float = -np.inf, hi: float = np.inf, optional: bool = False) -> None:
    if value is None and optional:
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
        hint = ""
        if isinstance(value, str):
            try:
                float(value)
                hint = f" (YAML reads {value} as text: write it with a point and a signed exponent, e.g. 1.0e+7)"
            except ValueError:
                pass
        raise ImportProfileError(f"{where}: expected a finite number in {lo:g}..{hi:g}, got {value!r}{hint}")


def _mapping(value, where: str, optional: bool = True) -> Mapping:
    if value is None and optional:
        return {}
    if not isinstance(value, Mapping):
        raise ImportProfileError(f"{where}: expected a mapping, got {value!r}")
    return value


def _known(spec: Mapping, keys: set[str], where: str) -> None:
    """ImportProfileError naming the first key of ``spec`` not in ``keys``."""
    unknown = sorted(str(k) for k in spec if k not in keys)
    if unknown:
        raise ImportProfileError(f"{where}{unknown[0]}: unknown key (expected {', '.join(sorted(keys))})")


def _check_columns(columns, where: str) -> None:
    for target, spec in _mapping(columns, f"{where}columns", optional=False).items():
        if target not in SI_UNIT:
            raise ImportProfileError(f"{where}columns.{target}: unknown target (expected one of {', '.join(SI_UNIT)})")
        spec = _mapping(spec, f"{where}columns.{target}", optional=False)
        _known(spec, COLUMN_KEYS, f"{where}columns.{target}.")
        if "column" not in spec:
            raise ImportProfileError(f"{where}columns.{target}: missing key 'column'")
        if not isinstance(spec["column"], (str, int)) or isinstance(spec["column"], bool):
            raise ImportProfileError(f"{where}columns.{target}.column: expected a column name")
        unit = spec.get("unit", SI_UNIT[target])
        if unit not in _DIMENSION[SI_UNIT[target]]:
            raise ImportProfileError(f"{where}columns.{target}.unit {unit!r} is not a unit of {SI_UNIT[target]}")
        for key in ("scale", "offset"):
            _number(spec.get(key), f"{where}columns.{target}.{key}", -1e30, 1e30, optional=True)


def _check_time(spec: Mapping, where: str, rate_required: bool) -> None:
    tspec = _mapping(spec.get("time"), f"{where}time")
    unknown = set(tspec) - {"column", "counter", "unit", "stamps"}
    if unknown:
        raise ImportProfileError(f"{where}time.{sorted(unknown)[0]}: unknown key (expected column, counter, unit, stamps)")
    if tspec.get("unit", "s") not in TIME_UNITS:
        raise ImportProfileError(f"{where}time.unit {tspec.get('unit')!r}: expected one of {', '.join(TIME_UNITS)}")
    if tspec.get("stamps", "sample") not in ("sample", "arrival"):
        raise ImportProfileError(f"{where}time.stamps {tspec.get('stamps')!r}: expected 'sample' or 'arrival'")
    if "stamps" in tspec and "column" not in tspec:
        raise ImportProfileError(f"{where}time.stamps: needs time.column")
    needs_rate = rate_required and "column" not in tspec
    _number(spec.get("rate_hz"), f"{where}rate_hz", 1e-6, 1e7, optional=not needs_rate)


def _check_reader(reader: Mapping, where: str) -> None:
    """A reader's type, its keys (each type has its own) and the ones it needs."""
    kind = reader.get("type", "csv")
    if kind not in READER_TYPES:
        raise ImportProfileError(f"{where}.type {kind!r}: expected one of {', '.join(READER_TYPES)}")
    unknown = set(reader) - READER_KEYS[kind] - {"type", "trailing_zero_rows"}
    if unknown:
        raise ImportProfileError(f"{where}.{sorted(unknown)[0]}: not a key of a {kind} reader "
                                 f"(keys: {', '.join(sorted(READER_KEYS[kind] | {'type', 'trailing_zero_rows'}))})")
    for key in REQUIRED_KEYS.get(kind, ()):
        if key not in reader:
            raise ImportProfileError(f"{where}.{key}: missing (a {kind} reader needs it)")
    for key in ("delimiter", "comment"):  # pandas takes a longer one as a regular expression
        if key in reader and not (isinstance(reader[key], str) and len(reader[key]) == 1):
            raise ImportProfileError(f"{where}.{key} {reader[key]!r}: expected one character")
    for key in ("skip_rows", "multi_id", "instance"):
        if key in reader:
            _number(reader[key], f"{where}.{key}", 0, 1e9)
    if reader.get("trailing_zero_rows", "keep") not in ("keep", "drop"):
        raise ImportProfileError(f"{where}.trailing_zero_rows {reader.get('trailing_zero_rows')!r}: "
                                 "expected 'keep' or 'drop'")


def _check_stream(name: str, spec, where: str, top_reader: Mapping) -> None:
    spec = _mapping(spec, where.rstrip("."), optional=False)
    safe_component(name, f"{where.rstrip('.')}: stream name", ImportProfileError)
    _known(spec, STREAM_KEYS, where)
    if "file" not in spec:
        raise ImportProfileError(f"{where}file: missing (the stream's file inside the data folder)")
    if not isinstance(spec["file"], str):
        raise ImportProfileError(f"{where}file: expected a file name, got {spec['file']!r}")
    _check_time(spec, where, rate_required=True)
    _check_columns(spec.get("columns"), where)
    _check_reader({**top_reader, **_mapping(spec.get("reader"), f"{where}reader")}, f"{where}reader")
    if spec.get("repeats", "flag") not in ("flag", "ignore"):
        raise ImportProfileError(f"{where}repeats {spec.get('repeats')!r}: expected 'flag' or 'ignore'")
    rng = spec.get("range")
    if rng is not None:
        rng = _mapping(rng, f"{where}range", optional=False)
        _known(rng, {"value", "unit"}, f"{where}range.")
        _number(rng.get("value"), f"{where}range.value", 1e-30, 1e30)
        dims = {SI_UNIT[c] for c in spec["columns"] if c in TRIAD_OF}
        if len(dims) != 1:
            raise ImportProfileError(f"{where}range: the stream must hold the columns of one triad kind "
                                     f"(gyro, accel or mag) to declare a range")
        dim = dims.pop()
        if rng.get("unit", dim) not in _DIMENSION[dim]:
            raise ImportProfileError(f"{where}range.unit {rng.get('unit')!r} is not a unit of {dim}")


def _check_shape(prof: Mapping, path: Path) -> None:
    """Sections are mappings and numbers are finite numbers, so reading the profile cannot fail later."""
    p = f"{path}: "
    _known(prof, TOP_KEYS, p)
    _number(prof.get("sample_rate_hz"), f"{p}sample_rate_hz", 1e-6, 1e7, optional="streams" in prof)
    unit = _mapping(prof.get("unit"), f"{p}unit")
    _known(unit, UNIT_KEYS, f"{p}unit.")
    if "serial" in unit:  # it names folders and is written into exports
        safe_component(unit["serial"], f"{p}unit.serial", ImportProfileError)
    plain_line(unit.get("model", ""), f"{p}unit.model", ImportProfileError)
    for key in ("name", "procedure", "rig"):
        plain_line(prof.get(key, ""), f"{p}{key}", ImportProfileError)
    if prof.get("procedure"):  # the procedure the session is for: a misspelt one is refused, not recorded
        from workbench.registry import procedure_names, unknown_hint

        names = procedure_names()
        if prof["procedure"] not in names:
            raise ImportProfileError(f"{p}procedure {prof['procedure']!r}: unknown procedure "
                                     f"{unknown_hint(prof['procedure'], names)}")
    site = _mapping(prof["site"], f"{p}site", optional=False)
    _known(site, SITE_KEYS, f"{p}site.")
    _number(site.get("latitude_deg"), f"{p}site.latitude_deg", -90, 90)
    for key in ("longitude_deg", "height_m", "table_zero_azimuth_deg"):
        _number(site.get(key), f"{p}site.{key}", -1e5, 1e5, optional=True)
    _number(site.get("field_norm_ut"), f"{p}site.field_norm_ut", 1.0, 1e3, optional=True)
    for key in ("time", "reader", "unit"):
        _mapping(prof.get(key), f"{p}{key}")
    if "streams" in prof:
        if "columns" in prof:
            raise ImportProfileError(f"{p}columns: give the columns under each stream of 'streams', not both")
        streams = _mapping(prof["streams"], f"{p}streams", optional=False)
        if not streams:
            raise ImportProfileError(f"{p}streams: no stream")
        for name, spec in streams.items():
            _check_stream(str(name), spec, f"{p}streams.{name}.", _mapping(prof.get("reader"), f"{p}reader"))
        base = prof.get("time_base", next(iter(streams)) if len(streams) == 1 else None)
        if base not in streams:
            raise ImportProfileError(f"{p}time_base {base!r}: must name one of the streams ({', '.join(streams)})")
    else:
        if "columns" not in prof:
            raise ImportProfileError(f"{p}missing key 'columns' (or 'streams')")
        _check_columns(prof["columns"], p)
        _check_reader(_mapping(prof.get("reader"), f"{p}reader"), f"{p}reader")
        _check_time({**prof, "rate_hz": prof.get("sample_rate_hz")}, p, rate_required=True)
    sections = _mapping(prof.get("sections"), f"{p}sections")
    _known(sections, SECTIONS_KEYS, f"{p}sections.")
    for name, step in _mapping(sections.get("steps"), f"{p}sections.steps").items():
        _check_section_step(_mapping(step, f"{p}sections.steps.{name}", optional=False), f"{p}sections.steps.{name}")
    _mapping(sections.get("inline"), f"{p}sections.inline")


def _check_section_step(step: Mapping, where: str) -> None:
    """A section's step: its kind, mount and the numbers of a turn (further keys travel with the step)."""
    if step.get("kind", "static") not in STEP_KINDS:
        raise ImportProfileError(f"{where}.kind {step.get('kind')!r} is unknown (expected one of {', '.join(STEP_KINDS)})")
    try:
        mount_matrix(step.get("mount", "z-down"))
    except RigLimitError as exc:
        raise ImportProfileError(f"{where}.mount: {exc}") from None
    for key in ("turn_deg", "table_rate_dps"):
        _number(step.get(key), f"{where}.{key}", -1e6, 1e6, optional=True)
    if step.get("axis", "z") not in ("x", "y", "z"):
        raise ImportProfileError(f"{where}.axis {step.get('axis')!r}: expected x, y or z")


def stream_specs(prof: Mapping) -> dict[str, dict]:
    """The profile's streams ({name: spec}); a single-file profile is one stream named :data:`SINGLE`."""
    if "streams" in prof:
        return {str(k): dict(v) for k, v in prof["streams"].items()}
    return {SINGLE: {"columns": prof["columns"], "time": prof.get("time") or {}, "rate_hz": prof["sample_rate_hz"]}}


def time_base(prof: Mapping) -> str:
    """Name of the stream whose instants the session keeps."""
    specs = stream_specs(prof)
    return str(prof.get("time_base", next(iter(specs))))


def load_profile(path: str | Path) -> dict:
    """Read and check an import profile; raises ImportProfileError naming the file and key."""
    path = Path(path)
    prof = load_yaml_file(path, error=ImportProfileError)  # size and alias expansion limited
    if not isinstance(prof, Mapping) or prof.get("format") != PROFILE_FORMAT:
        raise ImportProfileError(f"{path}: 'format' must be {PROFILE_FORMAT!r}")
    if "site" not in prof:
        raise ImportProfileError(f"{path}: missing key 'site'")
    if "streams" not in prof and "sample_rate_hz" not in prof:
        raise ImportProfileError(f"{path}: missing key 'sample_rate_hz'")
    _check_shape(prof, path)
    seen: dict[str, str] = {}
    for name, spec in stream_specs(prof).items():
        for target in spec["columns"]:
            if target in seen:
                raise ImportProfileError(f"{path}: streams.{name}.columns.{target}: already given by stream {seen[target]}")
            seen[target] = name
    missing = [c for c in (*GYRO, *ACCEL) if c not in seen]
    if missing:
        raise ImportProfileError(f"{path}: columns: no mapping for {', '.join(missing)}")
    return dict(prof)
