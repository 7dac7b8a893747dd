"""The runner: records a sequence on a rig into a session, step by step.

Every completed step is written at once: its samples to ``parts/step_NNNNN.parquet``
(atomically; plain, uncompressed columns, which are cheap to write and only read again on
resume), then one line (its record and the rig state after it) appended to the step log
``steps.jsonl``, so a run that is killed leaves every completed step readable and ``resume``
continues from the first incomplete step. The log is synced to disk after a step when
:data:`SYNC_INTERVAL_S` has passed since the last sync (after every step of a real rig, whose
steps last longer): a power cut loses at most that much recording, which resume records again
(a step whose part did not reach the disk whole is recorded again in any case). The manifest
``session.json`` is written twice: with the plan before anything moves, and complete when the
last step is done, when the samples (kept in memory, not read back from the parts) are
consolidated into ``samples.parquet`` (Snappy-compressed, dictionary-encoded step labels) and
the parts and the log removed. The rig's limits are
checked for the whole plan before anything moves.
"""

from __future__ import annotations

import json
import os
import shutil
import time
import uuid
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd

from workbench.calset import Unit
from workbench.errors import SessionError
from workbench.files import make_folder
from workbench.sequence import PlannedStep, Sequence
from workbench.session import FORMAT, STEP_LOG, Session, StepRecord, step_log, write_manifest

Progress = Callable[[int, int, StepRecord], None]
PARTS = "parts"
SYNC_INTERVAL_S = 1.0  # s, the step log is synced to disk at most this often
# how a step's part is written: plain columns (a part is read again only on resume)
PART_PARQUET = {"compression": None, "use_dictionary": False}
# how the consolidated samples are written: float columns do not repeat, so only the step
# labels are dictionary-encoded (a dictionary tried on every float column costs the most)
SAMPLES_PARQUET = {"compression": "snappy", "use_dictionary": ["step"]}


def _now() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def _planned_from_dict(d: dict) -> PlannedStep:
    known = {"kind", "mount", "table_angle", "table_rate", "duration_s", "temperature_c", "label"}
    return PlannedStep(d["kind"], np.asarray(d["mount"], float), d["table_angle"], d["table_rate"], d["duration_s"],
                       d["temperature_c"], d.get("label", ""), {k: v for k, v in d.items() if k not in known})


class Recording:
    """A session being recorded (in a folder, or in memory when ``out_dir`` is None)."""

    def __init__(self, out_dir: Path | None, manifest: dict, plan: list[PlannedStep]):
        self.out_dir = out_dir
        self.manifest = manifest
        self.plan = plan
        self.resumed = len(manifest["steps"])  # steps recorded before (their samples are in the parts)
        self.frames: list[pd.DataFrame] = []  # samples of the steps recorded here, for the consolidation
        self._synced = -float("inf")  # time.monotonic() of the last sync of the step log
        self._schema = None  # (column names and dtypes, the Arrow schema pandas would write for them)

    @property
    def done(self) -> int:
        return len(self.manifest["steps"])

    def add(self, samples: pd.DataFrame, record: StepRecord, rig_state: dict) -> None:
        step = record.to_dict()
        self.manifest["steps"].append(step)
        self.manifest["rig_state"] = rig_state
        self.frames.append(samples)
        if self.out_dir is None:
            return
        parts = self.out_dir / PARTS
        parts.mkdir(exist_ok=True)
        tmp = parts / f".step_{record.index:05d}.tmp"
        self._write(samples, tmp, PART_PARQUET)
        tmp.replace(parts / f"step_{record.index:05d}.parquet")
        line = json.dumps({"step": step, "rig_state": rig_state}, default=_json_default) + "\n"
        with open(self.out_dir / STEP_LOG, "a") as log:  # the step counts as recorded once this line is written
            log.write(line)
            log.flush()
            if time.monotonic() - self._synced >= SYNC_INTERVAL_S:
                os.fsync(log.fileno())
                self._synced = time.monotonic()

    def finish(self) -> Session:
        self.manifest["complete"] = True
        if self.out_dir is None:
            return _in_memory(self.manifest, pd.concat(self.frames, ignore_index=True))
        earlier = [_part(self.out_dir, s["index"]) for s in self.manifest["steps"][:self.resumed]]
        df = pd.concat([*earlier, *self.frames], ignore_index=True)
        session = _in_memory(self.manifest, df, self.out_dir)  # validated before anything is replaced
        tmp = self.out_dir / ".samples.parquet.tmp"
        self._write(df, tmp, SAMPLES_PARQUET)
        tmp.replace(self.out_dir / "samples.parquet")
        write_manifest(self.out_dir, self.manifest)
        (self.out_dir / STEP_LOG).unlink(missing_ok=True)
        shutil.rmtree(self.out_dir / PARTS, ignore_errors=True)
        return session


    def _write(self, frame: pd.DataFrame, path: Path, options: dict) -> None:
        """Write ``frame`` to the Parquet file ``path``: the bytes ``frame.to_parquet(path, index=False,
        **options)`` writes, from the frame's own column arrays (pandas' conversion and its schema,
        made again for every call, cost more than the write of a short step)."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        key = tuple(zip(frame.columns, map(str, frame.dtypes)))
        if self._schema is None or self._schema[0] != key:
            self._schema = key, pa.Schema.from_pandas(frame.iloc[:0], preserve_index=False)
        table = pa.Table.from_arrays([frame[c].to_numpy() for c in frame.columns], schema=self._schema[1])
        pq.write_table(table, path, **options)


def _json_default(value):
    """numpy scalars and arrays in a rig state, as JSON."""
    return np.asarray(value).tolist()


def _part(directory: Path, index: int) -> pd.DataFrame:
    """The samples of step ``index`` of an unfinished recording."""
    return pd.read_parquet(directory / PARTS / f"step_{index:05d}.parquet")


def read_parts(directory: Path) -> pd.DataFrame:
    """Concatenate the per-step sample files of an unfinished recording."""
    files = sorted((directory / PARTS).glob("step_*.parquet"))
    if not files:
        raise SessionError(f"{directory}: no recorded steps")
    return pd.concat([pd.read_parquet(f) for f in files], ignore_index=True)


def _in_memory(manifest: dict, df: pd.DataFrame, path: Path | None = None) -> Session:
    from workbench.session import Site, parse_manifest, validate_samples

    source = "<memory>" if path is None else str(path)
    fields, steps = parse_manifest(manifest, source)
    validate_samples(df, steps, fields["sample_rate_hz"], source)
    s = fields["site"]
    return Session(fields["id"], Unit(**fields["unit"]), Site(**s), fields["sample_rate_hz"], fields["procedure"],
                   steps, df, path, fields.get("options", {}), fields.get("rig"), fields.get("created"))


def start(sequence: Sequence, rig, unit: Unit, procedure: str, out_dir: Path | None,
          extra: dict | None = None) -> Recording:
    """Check the plan against the rig, then create the session folder and its manifest."""
    plan = sequence.expand()
    rig.check(plan)
    manifest = {
        "format": FORMAT, "id": str(uuid.uuid4()), "unit": {"serial": unit.serial, "model": unit.model},
        "site": rig.site.to_dict(), "sample_rate_hz": rig.fs, "procedure": procedure,
        "options": json.loads(json.dumps(dict(sequence.options), default=str)), "rig": rig.name,
        "created": _now(), "complete": False, "sequence": sequence.to_dict(),
        "planned": [p.to_dict() for p in plan], "steps": [], **(extra or {}),
    }
    if out_dir is not None:
        out_dir = Path(out_dir)
        if (out_dir / "session.json").exists():
            raise SessionError(f"{out_dir}: already holds a session (use --resume to continue it)")
        make_folder(out_dir, "session folder")
        write_manifest(out_dir, manifest)
    return Recording(out_dir, manifest, plan)


def reopen(out_dir: Path) -> Recording:
    """Reopen an interrupted recording for ``--resume``."""
    out_dir = Path(out_dir)
    path = out_dir / "session.json"
    if not path.exists():
        raise SessionError(f"{out_dir}: no session.json to resume")
    manifest = json.loads(path.read_text())
    if manifest.get("complete"):
        raise SessionError(f"{out_dir}: the session is already complete")
    if "planned" not in manifest:
        raise SessionError(f"{path}: no planned steps recorded; cannot resume")
    plan = [_planned_from_dict(p) for p in manifest["planned"]]
    # the steps (from the manifest, then the log) whose parts reached the disk whole, up to the first
    # missing or damaged one (a truncated part is recorded again, with every step after it); the rig
    # state after the last of them is where the resumed recording continues
    ok = {int(f.stem.split("_")[1]) for f in (out_dir / PARTS).glob("step_*.parquet")
          if _part_ok(f, int(f.stem.split("_")[1]))}
    kept = []
    for s in manifest["steps"]:
        if s["index"] != len(kept) or s["index"] not in ok:
            break
        kept.append(s)
    manifest["steps"] = kept
    for entry in step_log(out_dir):
        i = entry["step"]["index"]
        if i < len(manifest["steps"]):  # already kept; the last one's rig state is where the resume continues
            if i == len(manifest["steps"]) - 1:
                manifest["rig_state"] = entry["rig_state"]
            continue
        if i != len(manifest["steps"]) or i not in ok:
            break
        manifest["steps"].append(entry["step"])
        manifest["rig_state"] = entry["rig_state"]
    for f in (out_dir / PARTS).glob("step_*.parquet"):
        if int(f.stem.split("_")[1]) >= len(manifest["steps"]):
            f.unlink()  # orphaned or damaged: recorded again
    return Recording(out_dir, manifest, plan)


def _part_ok(path: Path, index: int) -> bool:
    """Whether a step part is a whole Parquet file holding samples of step ``index``."""
    import pyarrow.parquet as pq

    try:
        steps = pq.read_table(path, columns=["step"]).column("step").to_numpy()
    except (OSError, ValueError, KeyError):  # missing, truncated (no footer), no step column
        return False
    return len(steps) > 0 and bool(np.any(steps == index)) and bool(np.all((steps == index) | (steps == -1)))


def record(recording: Recording, rig, progress: Progress | None = None) -> Session:
    """Run the remaining planned steps on ``rig``; on any interruption make the rig safe and re-raise."""
    n = len(recording.plan)
    try:
        for i in range(recording.done, n):
            samples, rec = rig.perform(recording.plan[i], i)
            recording.add(samples, rec, rig.state.to_dict() if hasattr(rig, "state") else {})
            if progress is not None:
                progress(i, n, rec)
    except BaseException:
        rig.safe()
        raise
    finally:
        rig.close()
    return recording.finish()


def rig_state_for_resume(recording: Recording):
    """The saved rig state of an interrupted recording (for the simulated rig)."""
    from workbench.motion import RigState

    state = recording.manifest.get("rig_state")
    return None if state is None else RigState(**state)


__all__ = ["Recording", "start", "reopen", "record", "read_parts", "rig_state_for_resume"]
