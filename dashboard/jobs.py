"""Background runs of the dashboard: a detached ``workbench run`` per folder, read back from its files.

A run survives page reloads (its own process group). Its progress is read from what the runner
writes, never from the CLI's terminal output:

- ``job.json`` (written here): procedure, unit, command, pid, planned steps and rig time;
- the session's ``session.json`` (its ``planned`` steps, written before the first step) and the
  runner's append-only step log (one JSON line per completed step, :func:`workbench.session.recorded_steps`);
- ``result.json`` once analysed: summary lines (lab units) and warnings;
- ``exit_code`` (written by the shell wrapper when ``workbench run`` ends) and ``stderr.log``,
  whose last line is the CLI's one-line error when it fails (exit 2).

``stdout.log`` keeps the CLI's output for people (shown as is, never parsed).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from functools import lru_cache
from pathlib import Path

import pandas as pd

from dashboard.charts import downsample
from dashboard.roots import runs_dir
from workbench.errors import SessionError

REPO = Path(__file__).resolve().parents[1]
JOB_FILE = "job.json"  # written by start_run: procedure, unit, command, pid, planned steps and rig time
EXIT_FILE = "exit_code"  # written by the run's shell wrapper when `workbench run` ends
LOG_FILE = "stdout.log"  # the CLI's output for people (not parsed)
ERR_FILE = "stderr.log"  # its last line is the one-line error of a failed run
LOG_LINES = 200  # lines of stdout.log kept in RunStatus.log


def _workbench_cli() -> list[str]:
    script = Path(sys.executable).with_name("workbench")
    return [str(script)] if script.exists() else [sys.executable, "-m", "workbench.cli"]


_CHILDREN: dict[str, subprocess.Popen] = {}  # runs started by this server process (reaped on poll)


def start_run(procedure: str, grade: Path, seed: int | None = None, options: Mapping | None = None,
              expected_s: float | None = None, n_steps: int | None = None) -> Path:
    """Start ``workbench run PROC --unit GRADE --rig sim --out DIR`` detached; returns DIR.

    ``expected_s`` (s of rig time) and ``n_steps`` come from the procedure's sequence, so the
    progress shows its total before the runner has written anything; ``options`` are passed as
    ``--option key=JSON``.
    """
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%S")
    out = runs_dir() / f"{stamp}_{procedure}_{Path(grade).stem}"
    n = 1
    while out.exists():
        n += 1
        out = out.with_name(f"{stamp}_{procedure}_{Path(grade).stem}_{n}")
    out.mkdir(parents=True)
    cmd = [*_workbench_cli(), "run", procedure, "--unit", str(grade), "--rig", "sim", "--out", str(out / "output")]
    if seed is not None:
        cmd += ["--seed", str(int(seed))]
    for name, value in dict(options or {}).items():
        cmd += ["--option", f"{name}={json.dumps(value)}"]
    exit_tmp = out / f".{EXIT_FILE}.tmp"  # renamed into place, so a reader never sees it half-written
    wrapper = ["sh", "-c", f'"$@" > "{out / LOG_FILE}" 2> "{out / ERR_FILE}"; echo $? > "{exit_tmp}"; '
                           f'mv "{exit_tmp}" "{out / EXIT_FILE}"', "workbench-run", *cmd]
    proc = subprocess.Popen(wrapper, cwd=str(REPO), start_new_session=True, stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env={**os.environ, "COLUMNS": "100"})
    job = {"procedure": procedure, "unit": str(grade), "seed": seed, "options": dict(options or {}),
           "command": cmd, "pid": proc.pid, "started": time.time(), "expected_s": expected_s, "n_steps": n_steps}
    (out / JOB_FILE).write_text(json.dumps(job, indent=1, default=str))
    _CHILDREN[str(out)] = proc
    return out


@dataclass(frozen=True)
class RunStatus:
    """State of a dashboard run read from its folder.

    ``state`` is ``running``, ``done`` or ``failed``; ``progress`` the recorded fraction of the
    planned rig time (0..1, None when unknown); ``steps_done`` of ``steps_planned``;
    ``session_dir`` / ``result_dir`` the folders holding ``session.json`` / ``result.json`` once
    they exist; ``summary`` / ``warnings`` those of ``result.json``; ``error`` the CLI's one-line
    error of a failed run ("" otherwise); ``log`` the last LOG_LINES of its output.
    """

    folder: Path
    job: dict
    state: str
    progress: float | None
    steps_done: int
    steps_planned: int | None
    session_dir: Path | None
    result_dir: Path | None
    log: str
    exit_code: int | None
    summary: tuple[str, ...] = field(default=())
    warnings: tuple[str, ...] = field(default=())
    error: str = ""


def find(folder: Path, name: str) -> Path | None:
    """The shallowest folder under ``folder`` holding a file ``name`` (None if there is none)."""
    hits = sorted(folder.rglob(name), key=lambda p: len(p.parts))
    return hits[0].parent if hits else None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _recorded(session_dir: Path | None) -> tuple[int, float, int | None, float | None]:
    """(steps recorded, rig s recorded, steps planned, rig s planned) of a session being recorded.

    The runner writes the manifest with its ``planned`` steps first and appends every completed
    step to its step log; a session from elsewhere has no plan (None).
    """
    from workbench.session import recorded_steps

    if session_dir is None:
        return 0, 0.0, None, None
    try:
        manifest = json.loads((session_dir / "session.json").read_text())
        steps = recorded_steps(session_dir, manifest)
    except (OSError, json.JSONDecodeError, SessionError):  # being replaced right now: try again on the next poll
        return 0, 0.0, None, None
    planned = manifest.get("planned")
    t_done = float(sum(float(s.get("t_end", 0)) - float(s.get("t_start", 0)) for s in steps))
    if not planned:
        return len(steps), t_done, None, None
    return len(steps), t_done, len(planned), float(sum(float(p.get("duration_s", 0)) for p in planned))


def _result(result_dir: Path | None) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(summary lines, warnings) of ``result.json`` in ``result_dir`` (empty while it is not there)."""
    if result_dir is None:
        return (), ()
    try:
        doc = json.loads((result_dir / "result.json").read_text())
    except (OSError, json.JSONDecodeError):
        return (), ()
    return tuple(str(s) for s in doc.get("summary", [])), tuple(str(w) for w in doc.get("warnings", []))


def _tail(path: Path, lines: int) -> str:
    return "\n".join(path.read_text(errors="replace").splitlines()[-lines:]) if path.exists() else ""


def run_status(folder: Path) -> RunStatus:
    """Status of the run in ``folder`` (see :class:`RunStatus`); SessionError if it is not a run folder."""
    folder = Path(folder)
    try:
        job = json.loads((folder / JOB_FILE).read_text())
    except (OSError, json.JSONDecodeError):
        raise SessionError(f"{folder}: not a dashboard run (no readable {JOB_FILE})") from None
    child = _CHILDREN.get(str(folder))
    if child is not None:
        child.poll()  # reap it when it has ended
    # liveness first: the wrapper writes exit_code before it exits, so a dead wrapper without one was stopped
    alive = _alive(int(job.get("pid", 0) or 0))
    exit_path = folder / EXIT_FILE
    code: int | None = None
    if exit_path.exists():
        text = exit_path.read_text().strip()
        code = int(text) if text.lstrip("-").isdigit() else None
    session_dir, result_dir = find(folder, "session.json"), find(folder, "result.json")
    n_done, t_done, n_planned, t_planned = _recorded(session_dir)
    expected = t_planned or job.get("expected_s")
    if code == 0:
        state, progress = "done", 1.0
    elif code is None and alive:
        state = "running"
        progress = min(t_done / float(expected), 0.99) if expected else None
    else:
        state = "failed"
        progress = min(t_done / float(expected), 1.0) if expected else None
    errors = [line for line in _tail(folder / ERR_FILE, 50).splitlines() if line.strip()]
    summary, warnings = _result(result_dir)
    return RunStatus(folder, job, state, progress, n_done, n_planned or job.get("n_steps"), session_dir, result_dir,
                     _tail(folder / LOG_FILE, LOG_LINES), code, summary, warnings,
                     errors[-1] if state == "failed" and errors else "")


def list_runs() -> list[Path]:
    """Dashboard run folders, newest first."""
    root = runs_dir()
    if not root.is_dir():
        return []
    return sorted((p for p in root.iterdir() if (p / JOB_FILE).exists()), reverse=True)


def stop_run(folder: Path) -> None:
    """Stop a run this dashboard started (SIGTERM to its own process group, by its recorded pid)."""
    status = run_status(folder)
    if status.state == "running":
        try:
            os.killpg(int(status.job["pid"]), signal.SIGTERM)
        except ProcessLookupError:
            pass


@lru_cache(maxsize=2000)
def _part(path: str, mtime: float, max_points: int) -> pd.DataFrame:
    return downsample(pd.read_parquet(path), max_points=max_points)


def partial_samples(session_dir: Path, max_points: int = 3000) -> pd.DataFrame | None:
    """The samples recorded so far in a session folder, downsampled (None if none are readable yet).

    Reads the runner's per-step parts (``parts/step_*.parquet``, each read once and cached) or,
    once the run is complete, the consolidated samples file.
    """
    from workbench.session import samples_file

    files = [samples_file(session_dir)] if samples_file(session_dir) else sorted(session_dir.glob("parts/step_*.parquet"))
    frames = []
    for f in files:
        try:
            frames.append(_part(str(f), f.stat().st_mtime, max_points))
        except Exception:  # noqa: BLE001 - a part replaced while read, or a CSV: skip it on this poll
            continue
    if not frames:
        return None
    df = pd.concat(frames, ignore_index=True)
    return downsample(df, max_points=max_points) if "t" in df.columns else None
