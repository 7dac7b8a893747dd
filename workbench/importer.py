"""Import profiles: turn another tool's recording into a workbench session.

A profile (YAML, ``format: workbench-import/1``) says how to read the file, which of its
columns hold which quantity and in which unit (deg/s, g, mg, gauss, nT, raw counts with a
``scale``), how time is given (a time column, a sample counter, or the row number at a
sample rate), where the unit and site come from, and how sections of the recording become
steps (a sections file or inline sample-index ranges, each with its kind and mount).
See ``docs/formats.md`` for every key, and ``fixtures/import_profiles/`` for examples.
"""

from __future__ import annotations

import json
import uuid
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd
from workbench.calset import Unit, file_sha256
from workbench.confine import confined_path, plain_template
from workbench.errors import ImportProfileError, WorkbenchError
from workbench.sequence import mount_matrix
from workbench.session import (ACCEL, GYRO, MAG, STEP_KINDS, Session, Site, StepRecord, load_session,
                               validate_samples, write_session)
from workbench.safe_yaml import load_yaml_file
from workbench.staging import refuse_existing, staged_folder
from workbench.units import factor

PROFILE_FORMAT = "workbench-import/1"
_TARGETS = (*GYRO, *ACCEL, *MAG, "temp", "table_angle", "table_rate")
_SI = {**{c: "rad/s" for c in GYRO}, **{c: "m/s^2" for c in ACCEL}, **{c: "uT" for c in MAG},
       "temp": "degC", "table_angle": "rad", "table_rate": "rad/s"}
_DIMENSION = {"rad/s": {"rad/s", "deg/s", "deg/h"}, "m/s^2": {"m/s^2", "g", "mg", "ug"},
              "uT": {"uT", "ut", "nT", "gauss", "mgauss", "T"}, "rad": {"rad", "deg", "mrad"}, "degC": {"degC"}}


def load_profile(path: str | Path) -> dict:
    """Read and check an import profile; raises ImportProfileError naming the file and key."""
    path = Path(path)
    prof = load_yaml_file(path, error=ImportProfileError)  # size and alias expansion limited
    if not isinstance(prof, Mapping) or prof.get("format") != PROFILE_FORMAT:
        raise ImportProfileError(f"{path}: 'format' must be {PROFILE_FORMAT!r}")
    for key in ("columns", "site", "sample_rate_hz"):
        if key not in prof:
            raise ImportProfileError(f"{path}: missing key {key!r}")
    _check_shape(prof, path)
    for target, spec in prof["columns"].items():
        if target not in _TARGETS:
            raise ImportProfileError(f"{path}: columns.{target}: unknown target (expected one of {', '.join(_TARGETS)})")
        unit = spec.get("unit", _SI[target])
        if unit not in _DIMENSION[_SI[target]]:
            raise ImportProfileError(f"{path}: columns.{target}.unit {unit!r} is not a unit of {_SI[target]}")
        if "column" not in spec:
            raise ImportProfileError(f"{path}: columns.{target}: missing key 'column'")
    missing = [c for c in (*GYRO, *ACCEL) if c not in prof["columns"]]
    if missing:
        raise ImportProfileError(f"{path}: columns: no mapping for {', '.join(missing)}")
    return prof


def _number(value, where: str, lo: float = -np.inf, hi: float = np.inf, optional: bool = False) -> None:
    if value is None and optional:
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
        raise ImportProfileError(f"{where}: expected a finite number in {lo:g}..{hi:g}, got {value!r}")


def _check_shape(prof: Mapping, path: Path) -> None:
    """Sections are mappings and numbers are finite numbers, so reading the profile cannot fail later."""
    def mapping(value, where: str, optional: bool = True) -> Mapping:
        if value is None and optional:
            return {}
        if not isinstance(value, Mapping):
            raise ImportProfileError(f"{path}: {where}: expected a mapping, got {value!r}")
        return value
    _number(prof["sample_rate_hz"], f"{path}: sample_rate_hz", 1e-6, 1e7)
    site = mapping(prof["site"], "site", optional=False)
    _number(site.get("latitude_deg"), f"{path}: site.latitude_deg", -90, 90)
    for key in ("longitude_deg", "height_m", "table_zero_azimuth_deg"):
        _number(site.get(key), f"{path}: site.{key}", -1e5, 1e5, optional=True)
    for target, spec in mapping(prof["columns"], "columns", optional=False).items():
        spec = mapping(spec, f"columns.{target}", optional=False)
        if not isinstance(spec.get("column", ""), (str, int)) or isinstance(spec.get("column"), bool):
            raise ImportProfileError(f"{path}: columns.{target}.column: expected a column name")
        for key in ("scale", "offset"):
            _number(spec.get(key), f"{path}: columns.{target}.{key}", -1e30, 1e30, optional=True)
    for key in ("time", "reader", "unit"):
        mapping(prof.get(key), key)
    sections = mapping(prof.get("sections"), "sections")
    for name, step in mapping(sections.get("steps"), "sections.steps").items():
        mapping(step, f"sections.steps.{name}", optional=False)
    mapping(sections.get("inline"), "sections.inline")


def _read_table(path: Path, reader: Mapping) -> pd.DataFrame:
    try:
        if path.suffix == ".parquet" or reader.get("type") == "parquet":
            return pd.read_parquet(path)
        return pd.read_csv(path, sep=reader.get("delimiter", ","), skiprows=reader.get("skip_rows", 0),
                           comment=reader.get("comment"))
    except Exception as exc:  # pandas/pyarrow raise many types for files that are not tables
        raise WorkbenchError(f"{path}: not a readable recording ({type(exc).__name__}: {str(exc)[:120]})") from None


def _convert(raw: pd.DataFrame, prof: Mapping, source: str) -> pd.DataFrame:
    out = {}
    for target, spec in prof["columns"].items():
        col = spec["column"]
        if col not in raw.columns:
            raise ImportProfileError(f"{source}: profile column {col!r} (for {target}) not in the file "
                                     f"(columns: {', '.join(map(str, raw.columns[:12]))})")
        values = pd.to_numeric(raw[col], errors="coerce").to_numpy(float) * float(spec.get("scale", 1.0))
        values = values + float(spec.get("offset", 0.0))
        unit = spec.get("unit", _SI[target])
        out[target] = values if unit == "degC" else values * factor(unit) / factor(_SI[target])
    return pd.DataFrame(out)


def _time(raw: pd.DataFrame, prof: Mapping, rate: float, source: str) -> np.ndarray:
    tspec = prof.get("time") or {}
    if "column" in tspec:
        col = tspec["column"]
        if col not in raw.columns:
            raise ImportProfileError(f"{source}: time column {col!r} not in the file")
        scale = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}[tspec.get("unit", "s")]
        t = raw[col].to_numpy(float) * scale
        return t - t[0]
    if "counter" in tspec:
        col = tspec["counter"]
        if col not in raw.columns:
            raise ImportProfileError(f"{source}: counter column {col!r} not in the file")
        return raw[col].to_numpy(float) / rate
    return np.arange(len(raw)) / rate


def _sections(prof: Mapping, data_file: Path, profile_path: Path) -> dict:
    sec = prof.get("sections") or {}
    if "inline" in sec:
        ranges = sec["inline"]
    elif "file" in sec:
        name = plain_template(str(sec["file"]), {"stem"}, f"{profile_path}: sections.file", ImportProfileError)
        f = confined_path(data_file.parent, name.format(stem=data_file.stem), f"{profile_path}: sections.file",
                          ImportProfileError)
        try:
            ranges = json.loads(f.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise ImportProfileError(f"{f}: cannot read the sections file ({exc})") from None
    else:
        return {}
    return {name: (r["start"], r["end"]) if isinstance(r, Mapping) else tuple(r) for name, r in ranges.items()}


def import_file(profile_path: str | Path, data_file: str | Path, out_dir: str | Path) -> Session:
    """Import ``data_file`` through the profile into a session folder ``out_dir``; returns it loaded."""
    profile_path, data_file, out_dir = Path(profile_path), Path(data_file), Path(out_dir)
    refuse_existing(out_dir, "--out session folder")
    prof = load_profile(profile_path)
    if not data_file.exists():
        raise WorkbenchError(f"{data_file}: no such file")
    raw = _read_table(data_file, prof.get("reader") or {})
    rate = float(prof["sample_rate_hz"])
    df = _convert(raw, prof, str(data_file))
    df.insert(0, "t", _time(raw, prof, rate, str(data_file)))
    counter = raw[(prof.get("time") or {}).get("counter")].to_numpy() if "counter" in (prof.get("time") or {}) \
        else np.arange(len(raw))
    step = np.full(len(df), -1, dtype=np.int64)
    steps: list[StepRecord] = []
    step_specs = (prof.get("sections") or {}).get("steps", {})
    for i, (name, (a, b)) in enumerate(sorted(_sections(prof, data_file, profile_path).items(), key=lambda kv: kv[1][0])):
        spec = step_specs.get(name)
        if spec is None:
            raise ImportProfileError(f"{profile_path}: sections.steps: no entry for section {name!r}")
        kind = spec.get("kind", "static")
        if kind not in STEP_KINDS:
            raise ImportProfileError(f"{profile_path}: sections.steps.{name}.kind {kind!r} is unknown")
        sel = (counter >= a) & (counter < b)
        if not sel.any():
            raise ImportProfileError(f"{data_file}: section {name} ({a}..{b}) selects no samples")
        step[sel] = i
        t = df["t"].to_numpy()[sel]
        extra = {k: v for k, v in spec.items() if k not in ("kind", "mount", "table_rate_dps")}
        mount = mount_matrix(spec.get("mount", "z-down"))
        rate_dps = spec.get("table_rate_dps")
        if rate_dps is None and "turn_deg" in spec:
            # a turn about a body axis is a turn about the table axis by the axis's down component
            axis_down = (mount @ np.eye(3)["xyz".index(spec.get("axis", "z"))])[2]
            rate_dps = spec["turn_deg"] * axis_down / (t[-1] - t[0] + 1.0 / rate)
        steps.append(StepRecord(i, kind, float(t[0]), float(t[-1]) + 0.5 / rate, mount, 0.0,
                                float(np.radians(rate_dps or 0.0)), None, name, extra))
    df.insert(1, "step", step)
    s = prof["site"]
    site = Site(float(s["latitude_deg"]), float(s.get("longitude_deg") or 0.0), float(s.get("height_m") or 0.0),
                s.get("table_zero_azimuth_deg"))
    validate_samples(df, steps, rate, str(data_file))
    u = prof.get("unit") or {}
    sha = file_sha256(data_file)
    session = Session(str(uuid.uuid5(uuid.NAMESPACE_OID, sha)),
                      Unit(str(u.get("serial", data_file.stem)), str(u.get("model", ""))), site, rate,
                      str(prof.get("procedure", "")), steps, df,
                      options={"imported_from": str(data_file), "source_sha256": sha, "profile": profile_path.name},
                      rig=str(prof.get("rig", "imported")))
    with staged_folder(out_dir, "--out session folder") as tmp:  # whole or not at all
        write_session(session, tmp)
    return load_session(out_dir)
