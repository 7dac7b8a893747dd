"""Import profiles: turn another tool's recording into a workbench session.

A profile (YAML, ``format: workbench-import/1``) says how to read the recording, which
columns hold which quantity in which unit (deg/s, g, mg, gauss, nT, degC, raw counts with a
``scale``; a sign or an axis swap per column), how time is given (a time column, a sample
counter, the row number at a sample rate, or host arrival stamps from which the sampling
instants are reconstructed), where the unit and site come from, and how sections of the
recording become steps (a sections file or inline sample-index ranges, each with its kind and
mount; no ``sections``: the whole recording is one ``free`` step). A recording of several
files (``streams``, one per sensor, each with its own clock and rate) is merged onto the
instants of its ``time_base`` stream (:mod:`workbench.importers.merge`); repeated and
saturated samples are flagged in the ``flags`` column so fits leave them out.
See ``docs/formats.md`` for every key, and ``fixtures/import_profiles/`` for examples.
"""

from __future__ import annotations

import json
import uuid
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from workbench.confine import confined_path, plain_template, safe_component
from workbench.errors import ImportProfileError, WorkbenchError
from workbench.files import file_sha256
from workbench.importers.merge import GAP_PERIODS, merge_streams
from workbench.importers.profile import PROFILE_FORMAT, SINGLE, load_profile, stream_specs, time_base
from workbench.importers.streams import Stream, read_stream
from workbench.importers.summary import import_summary
from workbench.sequence import mount_matrix
from workbench.session import Session, Site, StepRecord, load_session, validate_samples, write_session
from workbench.staging import refuse_existing, staged_folder
from workbench.values import Unit

__all__ = ["PROFILE_FORMAT", "import_file", "load_profile"]


def _sections(prof: Mapping, data_file: Path, profile_path: Path) -> dict:
    sec = prof.get("sections") or {}
    if "inline" in sec:
        ranges = sec["inline"]
    elif "file" in sec:
        name = plain_template(str(sec["file"]), {"stem"}, f"{profile_path}: sections.file", ImportProfileError)
        folder = data_file if data_file.is_dir() else data_file.parent
        f = confined_path(folder, name.format(stem=data_file.stem), f"{profile_path}: sections.file",
                          ImportProfileError)
        try:
            ranges = json.loads(f.read_bytes())
        except (OSError, ValueError) as exc:  # ValueError: not JSON, or not UTF-8 text
            raise ImportProfileError(f"{f}: cannot read the sections file ({exc})") from None
        where = str(f)
    else:
        return {}
    return _ranges(ranges, where if "file" in sec and "inline" not in sec else f"{profile_path}: sections.inline")


def _ranges(ranges, where: str) -> dict[str, tuple[int, int]]:
    """{section: (start, end)} sample-counter ranges (end exclusive) from ``{name: {start, end}}`` or
    ``{name: [start, end]}``; ImportProfileError naming ``where`` and the section otherwise."""
    if not isinstance(ranges, Mapping):
        raise ImportProfileError(f"{where}: expected {{section: {{start: N, end: N}}}}, got {type(ranges).__name__}")
    out = {}
    for name, r in ranges.items():
        pair = (r.get("start"), r.get("end")) if isinstance(r, Mapping) else tuple(r) if isinstance(r, list) else ()
        if len(pair) != 2 or not all(isinstance(v, int) and not isinstance(v, bool) for v in pair) \
                or not 0 <= pair[0] < pair[1]:
            raise ImportProfileError(f"{where}: section {name}: expected whole sample counts 0 <= start < end, "
                                     f"got {r!r}")
        out[str(name)] = pair
    return out


def _section_steps(prof: Mapping, sections: dict, t: np.ndarray, counter: np.ndarray, rate: float,
                   profile_path: Path, data: Path, end: int) -> tuple[np.ndarray, list[StepRecord]]:
    """Step labels (N,) and records from the profile's sections (sample-counter ranges, end exclusive);
    ``end`` the time base's last counter + 1. Sections that overlap, or reach past the recording (the
    sections of another recording), are refused naming them."""
    step = np.full(len(t), -1, dtype=np.int64)
    steps: list[StepRecord] = []
    step_specs = (prof.get("sections") or {}).get("steps", {})
    ordered = sorted(sections.items(), key=lambda kv: kv[1][0])
    for (n0, (a0, b0)), (n1, (a1, b1)) in zip(ordered, ordered[1:]):
        if a1 < b0:
            raise ImportProfileError(f"{data}: section {n1} ({a1}..{b1}) overlaps section {n0} ({a0}..{b0})")
    for name, (a, b) in ordered:
        if b > end:
            raise ImportProfileError(f"{data}: section {name} ({a}..{b}) reaches past the recording's "
                                     f"{end} samples (the sections of another recording?)")
    for i, (name, (a, b)) in enumerate(ordered):
        spec = step_specs.get(name)
        if spec is None:
            raise ImportProfileError(f"{profile_path}: sections.steps: no entry for section {name!r}")
        kind = spec.get("kind", "static")  # kind, mount and turn checked with the profile
        sel = (counter >= a) & (counter < b)
        if not sel.any():
            raise ImportProfileError(f"{data}: section {name} ({a}..{b}) selects no samples")
        step[sel] = i
        ts = t[sel]
        extra = {k: v for k, v in spec.items() if k not in ("kind", "mount", "table_rate_dps")}
        mount = mount_matrix(spec.get("mount", "z-down"))
        rate_dps = spec.get("table_rate_dps")
        if rate_dps is None and "turn_deg" in spec:
            # a turn about a body axis is a turn about the table axis by the axis's down component
            axis_down = (mount @ np.eye(3)["xyz".index(spec.get("axis", "z"))])[2]
            rate_dps = spec["turn_deg"] * axis_down / (ts[-1] - ts[0] + 1.0 / rate)
        steps.append(StepRecord(i, kind, float(ts[0]), float(ts[-1]) + 0.5 / rate, mount, 0.0,
                                float(np.radians(rate_dps or 0.0)), None, name, extra))
    return step, steps


def _free_steps(t: np.ndarray, rate: float) -> tuple[np.ndarray, list[StepRecord]]:
    """The whole recording as ``free`` steps (motion by hand), one per stretch between sampling gaps."""
    cuts = np.flatnonzero(np.diff(t) > GAP_PERIODS / rate) + 1
    starts, stops = np.r_[0, cuts], np.r_[cuts, len(t)]
    step = np.empty(len(t), dtype=np.int64)
    steps = []
    for i, (a, b) in enumerate(zip(starts, stops)):
        step[a:b] = i
        steps.append(StepRecord(i, "free", float(t[a]), float(t[b - 1]) + 0.5 / rate, np.eye(3), 0.0, 0.0, None,
                                "free" if i == 0 else f"free_{i + 1}", {}))
    return step, steps


def _read_streams(prof: Mapping, profile_path: Path, data: Path) -> dict[str, Stream]:
    reader = prof.get("reader") or {}
    out = {}
    clocks: dict = {}  # arrival-clock fits by stamps, shared by the streams of one read
    for name, spec in stream_specs(prof).items():
        if name == SINGLE and "streams" not in prof:
            if data.is_dir() and reader.get("type") != "rosbag":  # a ROS 2 bag is a folder
                raise WorkbenchError(f"{data}: is a folder; this profile ({profile_path.name}) reads one file")
            path, where = data, str(data)
        else:
            if not data.is_dir():
                raise WorkbenchError(f"{data}: not a folder; profile {profile_path.name} reads streams from a "
                                     "data folder")
            where = f"{profile_path}: streams.{name}"
            path = confined_path(data, spec["file"], f"{where}.file", ImportProfileError)
        out[name] = read_stream(name, spec, path, reader, where, clocks)
    return out


def import_file(profile_path: str | Path, data_file: str | Path, out_dir: str | Path) -> Session:
    """Import a recording through the profile into a session folder ``out_dir``; returns it loaded.

    ``data_file`` is the recording's file (a single-file profile) or its folder (a profile
    with ``streams``). The import summary (rates, clocks, gaps, repeated and saturated
    samples, what was done) is in ``session.options["import"]`` (:mod:`workbench.importers.summary`).
    """
    profile_path, data, out_dir = Path(profile_path), Path(data_file), Path(out_dir)
    refuse_existing(out_dir, "--out session folder")
    prof = load_profile(profile_path)
    if not data.exists():
        raise WorkbenchError(f"{data}: no such file or folder")
    if "serial" not in (prof.get("unit") or {}):  # the data's name is the serial: it names folders, goes into exports
        safe_component(data.stem, f"{profile_path}: no unit.serial, and the data's name", ImportProfileError)
    streams = _read_streams(prof, profile_path, data)
    base = time_base(prof)
    merged = merge_streams(streams, base)
    df = merged.samples
    if len(df) < 2:
        raise ImportProfileError(f"{profile_path}: time_base {base}: fewer than 2 samples where every stream has data")
    if "streams" in prof:
        rate = float(streams[base].rate_hz)
    else:
        rate = float(prof["sample_rate_hz"])
    t = df["t"].to_numpy()
    counter = streams[base].index[merged.kept]
    sections = _sections(prof, data, profile_path)
    if sections:
        step, steps = _section_steps(prof, sections, t, counter, rate, profile_path, data,
                                     int(streams[base].index[-1]) + 1)
    else:
        step, steps = _free_steps(t, rate)
    df.insert(1, "step", step)
    if not (df["flags"] != 0).any() and "streams" not in prof:
        df = df.drop(columns="flags")
    s = prof["site"]
    site = Site(float(s["latitude_deg"]), float(s.get("longitude_deg") or 0.0), float(s.get("height_m") or 0.0),
                s.get("table_zero_azimuth_deg"), *([float(s["field_norm_ut"])] if "field_norm_ut" in s else []))
    validate_samples(df, steps, rate, str(data))
    summary = import_summary(streams, base, merged, steps, bool(sections))
    summary["axis_check"] = _axis_checks(df)
    u = prof.get("unit") or {}
    sha = _source_sha(streams)
    session = Session(str(uuid.uuid5(uuid.NAMESPACE_OID, sha)),
                      Unit(str(u.get("serial", data.stem)), str(u.get("model", ""))), site, rate,
                      str(prof.get("procedure", "")), steps, df,
                      options={"imported_from": str(data), "source_sha256": sha, "profile": profile_path.name,
                               "import": summary},
                      rig=str(prof.get("rig", "imported")))
    with staged_folder(out_dir, "--out session folder") as tmp:  # whole or not at all
        write_session(session, tmp)
    return load_session(out_dir)


def _axis_checks(df: pd.DataFrame) -> list[dict]:
    """The gyro against the accelerometer and magnetometer directions (:mod:`workbench.importers.axes`)."""
    from workbench.importers.axes import check_axes
    from workbench.session import FLAG_SATURATED

    flags = df["flags"].to_numpy() if "flags" in df.columns else np.zeros(len(df), np.int64)
    t, gyro = df["t"].to_numpy(), df[["gx", "gy", "gz"]].to_numpy()
    out = []
    for ref, cols in (("accel", ["ax", "ay", "az"]), ("mag", ["mx", "my", "mz"])):
        if not all(c in df.columns for c in cols):
            continue
        # saturated samples misstate the motion; an interpolation across a left-out repeat does not
        bits = FLAG_SATURATED["gyro"] | FLAG_SATURATED[ref]
        c = check_axes(t, gyro, df[cols].to_numpy(), ref, (flags & bits) == 0)
        out.append({"reference": ref, "agrees": c.agrees, "best": c.best.tolist(), "windows": c.windows,
                    "rms_identity_deg": c.rms_identity_deg, "rms_best_deg": c.rms_best_deg,
                    "message": c.message()})
    return out


def _path_sha256(path: Path) -> str:
    """SHA-256 of a file, or of the names and digests of a folder's files (a ROS 2 bag is a folder)."""
    if not path.is_dir():
        return file_sha256(path)
    import hashlib

    parts = {str(p.relative_to(path)): file_sha256(p) for p in sorted(path.rglob("*")) if p.is_file()}
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def _source_sha(streams: Mapping[str, Stream]) -> str:
    """SHA-256 of the source file (one stream) or of the streams' names and file digests."""
    by_source = {s.source: _path_sha256(Path(s.source)) for s in streams.values()}  # a shared file hashed once
    digests = {name: by_source[s.source] for name, s in streams.items()}
    if len(set(digests.values())) == 1:  # one file (a log holding every stream)
        return next(iter(digests.values()))
    import hashlib

    return hashlib.sha256(json.dumps(digests, sort_keys=True).encode()).hexdigest()
