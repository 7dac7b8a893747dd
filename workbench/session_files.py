"""The files of a session folder: ``session.json`` (read, parse, write), the step log, the samples file.

:func:`read_manifest` / :func:`parse_manifest` read and check the manifest, :func:`step_log` and
:func:`recorded_steps` the completed steps of an unfinished recording, :func:`read_samples` the
samples table (Parquet or CSV), :func:`write_manifest` / :func:`write_session` write atomically.
Re-exported by :mod:`workbench.session`.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from workbench.confine import plain_line, safe_component
from workbench.errors import SessionError
from workbench.files import atomic_write_text
from workbench.session_types import FORMAT, STEP_LOG, StepRecord, finite

if TYPE_CHECKING:
    from workbench.session import Session

def samples_file(directory: Path) -> Path | None:
    """The samples file of a session folder (Parquet preferred, then CSV), or None."""
    for name in ("samples.parquet", "samples.csv"):
        if (directory / name).exists():
            return directory / name
    return None


def read_manifest(directory: Path) -> dict:
    """The parsed ``session.json`` of a session folder; SessionError when missing, not JSON or not :data:`FORMAT`."""
    mpath = directory / "session.json"
    if not directory.is_dir():
        raise SessionError(f"{directory}: not a session folder")
    if not mpath.exists():
        raise SessionError(f"{directory}: no session.json")
    try:
        data = json.loads(mpath.read_bytes())  # UTF-8 (or -16/-32 with a BOM), as JSON allows
    except json.JSONDecodeError as exc:
        raise SessionError(f"{mpath}: not valid JSON (line {exc.lineno}: {exc.msg})") from None
    except UnicodeDecodeError:
        raise SessionError(f"{mpath}: not valid JSON (not UTF-8 text)") from None
    if not isinstance(data, Mapping):
        raise SessionError(f"{mpath}: expected a JSON object, got {type(data).__name__}")
    fmt = data.get("format")
    if fmt != FORMAT:
        raise SessionError(f"{mpath}: format {fmt!r} is not {FORMAT!r}")
    return data


def step_log(directory: Path) -> list[dict]:
    """The entries (``{"step": {...}, "rig_state": {...}}``) of an unfinished recording's step log.

    In step order, the last entry of a step index winning (a step recorded again on resume);
    a last line cut short by a kill is ignored. Empty when there is no log.
    """
    try:
        lines = (Path(directory) / STEP_LOG).read_bytes().decode("utf-8", "replace").splitlines()
    except FileNotFoundError:
        return []
    entries: dict[int, dict] = {}
    for n, line in enumerate(lines):
        try:
            entry = json.loads(line)
        except json.JSONDecodeError:
            if n == len(lines) - 1:
                break  # the line being written when the recording was killed
            raise SessionError(f"{directory / STEP_LOG}: line {n + 1} is not valid JSON") from None
        step = entry.get("step") if isinstance(entry, dict) else None
        index = step.get("index") if isinstance(step, dict) else None
        if not isinstance(index, int) or isinstance(index, bool):
            raise SessionError(f"{directory / STEP_LOG}: line {n + 1}: expected {{\"step\": {{\"index\": N, ...}}, ...}}")
        entries[index] = entry
    return [entries[i] for i in sorted(entries)]


def recorded_steps(directory: Path, manifest: Mapping) -> list[dict]:
    """The completed steps of a session folder: the manifest's, and those of the step log of a
    recording that has not finished (the manifest is rewritten only when it finishes)."""
    steps = list(manifest.get("steps", []))
    if manifest.get("complete"):
        return steps
    logged = step_log(directory)
    known = {s.get("index") for s in steps}
    return steps + [e["step"] for e in logged if e["step"]["index"] not in known]


def parse_manifest(data: Mapping, source: str) -> tuple[dict, list[StepRecord]]:
    """Validate a manifest dict; returns (fields, step records)."""
    for key in ("unit", "site", "sample_rate_hz", "steps"):
        if key not in data:
            raise SessionError(f"{source}: missing field {key!r}")
    unit = data["unit"]
    if not isinstance(unit, Mapping):
        raise SessionError(f"{source}: unit: expected an object with serial and model, got {unit!r}")
    safe_component(unit.get("serial"), f"{source}: unit.serial", SessionError)  # it names folders and exports
    plain_line(unit.get("model", ""), f"{source}: unit.model", SessionError)
    site = data["site"]
    if not isinstance(site, Mapping) or site.get("latitude_deg") is None:
        raise SessionError(f"{source}: site.latitude_deg is missing")
    lat = finite(site["latitude_deg"], f"{source}: site.latitude_deg")
    if not -90 <= lat <= 90:
        raise SessionError(f"{source}: site.latitude_deg {lat} is outside -90..90")
    for key in ("longitude_deg", "height_m", "table_zero_azimuth_deg", "field_norm_ut"):
        if site.get(key) is not None:
            finite(site[key], f"{source}: site.{key}")
    rate = data["sample_rate_hz"]
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0 < rate < float("inf"):
        raise SessionError(f"{source}: sample_rate_hz must be a positive number")
    if not isinstance(data["steps"], list):
        raise SessionError(f"{source}: steps: expected a list of step objects")
    steps = [StepRecord.from_dict(s, source) for s in data["steps"]]
    idx = [s.index for s in steps]
    if len(set(idx)) != len(idx):
        raise SessionError(f"{source}: duplicate step index")
    ordered = sorted(steps, key=lambda s: s.t_start)
    for a, b in zip(ordered, ordered[1:]):
        if b.t_start < a.t_end - 1e-9:
            raise SessionError(f"{source}: step {b.index} overlaps step {a.index}")
    return dict(data), steps


def read_samples(path: Path) -> pd.DataFrame:
    """Read a samples file (Parquet or CSV) into a DataFrame."""
    try:
        if path.suffix == ".parquet":
            return pd.read_parquet(path)
        return pd.read_csv(path)
    except Exception as exc:  # pyarrow / pandas raise many types for unreadable files
        raise SessionError(f"{path}: cannot read samples ({type(exc).__name__}: {str(exc)[:120]})") from None


def write_manifest(directory: Path, manifest: Mapping) -> None:
    """Write ``session.json`` atomically."""
    atomic_write_text(directory / "session.json", json.dumps(manifest, indent=1) + "\n")


def write_session(session: Session, directory: str | Path) -> Path:
    """Write a whole in-memory session to ``directory`` (Parquet samples + manifest)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    tmp = directory / ".samples.parquet.tmp"
    session.samples.to_parquet(tmp, index=False)
    tmp.replace(directory / "samples.parquet")
    write_manifest(directory, session.manifest())
    session.path = directory
    return directory
