"""Shared helpers of the dashboard pages: store, lab units, pickers, runs, errors, figures.

Pages call the library only; this module holds the Streamlit glue every page needs:

- :func:`store` — the store named by ``WORKBENCH_DB`` (cached per URL);
- :func:`lab` — an SI value (± sigma) in a lab unit, through ``workbench.units``;
- :func:`grade_picker` / :func:`unit_grades` — the grade fixtures ``fixtures/units/*.yaml``;
- :func:`option_inputs` — widgets for a procedure's ``DEFAULTS``;
- :func:`build_sequence` / :func:`show_sequence` — a procedure's sequence before it runs;
- :func:`start_run` / :func:`run_status` / :func:`list_runs` / :func:`stop_run` — a
  ``workbench run`` subprocess in its own folder, so a long run survives page reloads and its
  progress is read back from the files it writes;
- :func:`show_error` / :func:`guarded` — a :class:`WorkbenchError` as a readable ``st.error``;
- :func:`show_result` / :func:`show_figures` — summary, warnings and figures of a
  :class:`ProcedureResult` (or the PNGs of an output folder);
- :func:`session_picker` / :func:`analyze_session` / :func:`result_picker` — what an
  analysis page needs to get a ``ProcedureResult`` for a recorded session;
- :func:`downsample` — min/max envelope of long sample series for responsive plots.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pandas as pd
import streamlit as st

from dashboard import roots
from workbench import registry, units
from workbench.errors import SessionError, WorkbenchError
from workbench.procedure import ProcedureResult
from workbench.store import Store, default_url

REPO = Path(__file__).resolve().parents[1]
UNITS_DIR = REPO / "fixtures" / "units"
JOB_FILE = "job.json"  # written by start_run: procedure, unit, command, pid, expected duration
EXIT_FILE = "exit_code"  # written by the run's shell wrapper when `workbench run` ends
LOG_FILE = "run.log"
LOG_LINES = 200  # lines of run.log kept in RunStatus.log (the summary and any error are at the end)


# -- store and errors ------------------------------------------------------------------
@st.cache_resource(show_spinner=False)
def _store(url: str) -> Store:
    return Store(url)


def store() -> Store:
    """The store named by ``WORKBENCH_DB`` (default ``sqlite:///workbench.db``); raises StoreError."""
    return _store(default_url())


def show_error(exc: BaseException, context: str = "") -> None:
    """Show ``exc`` as a one-line ``st.error`` (a WorkbenchError's message names the place at fault)."""
    kind = type(exc).__name__
    prefix = f"{context}: " if context else ""
    if isinstance(exc, WorkbenchError):
        st.error(f"{prefix}{exc}  \n({kind})", icon="⚠️")
    else:  # a bug in a procedure: say so, but keep the page usable
        st.error(f"{prefix}unexpected {kind}: {str(exc)[:300]}", icon="🐞")


@contextmanager
def guarded(context: str = "", catch_all: bool = False) -> Iterator[None]:
    """Run a block; a WorkbenchError (or any error with ``catch_all``) becomes :func:`show_error`.

    The page continues after the block, so callers must not rely on values the block would set.
    """
    try:
        yield
    except WorkbenchError as exc:
        show_error(exc, context)
    except Exception as exc:  # noqa: BLE001 - only with catch_all, for third-party procedure code
        if not catch_all:
            raise
        show_error(exc, context)


# -- lab units -----------------------------------------------------------------------
def lab(value_si: Any, unit: str, sigma_si: Any = None, digits: int = 4) -> str:
    """``value_si`` (± ``sigma_si``) in lab ``unit`` with its label, e.g. ``'0.21 ± 0.01 °/h'``.

    Units are those of ``workbench.units`` (``deg/h``, ``deg/sqrt(h)``, ``mg``, ``ug/sqrt(Hz)``,
    ``ppm``, ``mrad``, ...). NaN / None means not observed and is shown as such.
    """
    if value_si is None or not np.isfinite(float(value_si)):
        return "not observed"
    if sigma_si is None:
        return units.fmt(float(value_si), unit, digits)
    sig = (f"{units.to_unit(float(sigma_si), unit):.2g}" if np.isfinite(float(sigma_si)) else "(σ not observed)")
    return f"{units.to_unit(float(value_si), unit):.{digits}g} ± {sig} {units.label(unit)}"


def lab_array(values_si: Any, unit: str) -> np.ndarray:
    """An SI array converted to lab ``unit`` (NaN kept), for tables and plots."""
    return np.asarray(units.to_unit(np.asarray(values_si, float), unit), float)


# -- unit grades, options, sequences ---------------------------------------------------
def unit_grades(directory: Path | None = None) -> dict[str, Path]:
    """Grade fixtures by name (file stem), sorted: ``{'hg1700': Path('.../hg1700.yaml'), ...}``."""
    return {p.stem: p for p in sorted((directory or UNITS_DIR).glob("*.yaml"))}


def grade_picker(label: str = "Unit grade", key: str = "grade") -> Path | None:
    """A select box over ``fixtures/units/*.yaml``; returns the chosen fixture path (None if none exist)."""
    grades = unit_grades()
    if not grades:
        st.info(f"No unit grade fixtures in {UNITS_DIR}.")
        return None
    name = st.selectbox(label, list(grades), key=key)
    return grades[name]


@st.cache_resource(show_spinner=False)
def _spec(path: str, mtime: float):
    from workbench.grades import load_spec

    return load_spec(path)


def load_spec(path: Path):
    """The SensorSpec of a grade fixture (cached per file version); raises WorkbenchError."""
    return _spec(str(path), Path(path).stat().st_mtime)


def procedure_picker(label: str = "Procedure", key: str = "procedure") -> ModuleType | None:
    """A select box over ``registry.procedures()`` showing titles; None (with a note) when none exist."""
    procs = registry.procedures()
    if not procs:
        st.info("No procedures are installed yet (procedures/*.py).")
        return None
    names = sorted(procs)
    name = st.selectbox(label, names, key=key, format_func=lambda n: f"{n} — {getattr(procs[n], 'TITLE', n)}")
    return procs[name]


# unit suffixes of names (longest first) -> the lab unit shown in labels and column headers
OPTION_UNITS = (("_deg_h_sqrt_h", "°/h/√h"), ("_m_s_h_sqrt_h", "m/s/h/√h"), ("_c_per_min", "°C/min"),
                ("_deg_h", "°/h"), ("_deg_s", "°/s"), ("_dps2", "°/s²"), ("_dps", "°/s"), ("_deg", "°"),
                ("_mrad", "mrad"), ("_mg", "mg"), ("_ppm", "ppm"), ("_ut", "µT"), ("_hz", "Hz"), ("_s", "s"),
                ("_c", "°C"))


def lab_label(name: str) -> str:
    """A snake-case name with a unit suffix (an option, a table column) for people:
    ``'gyro_bias_instability_deg_h'`` -> ``'gyro bias instability (°/h)'``."""
    for suffix, unit in OPTION_UNITS:
        if name.endswith(suffix) and len(name) > len(suffix):
            return f"{name[:-len(suffix)].replace('_', ' ')} ({unit})"
    return name.replace("_", " ")


def option_inputs(proc: ModuleType, key: str, stage: str | None = None) -> dict:
    """Widgets built from the procedure's declared options (:mod:`workbench.options`) of ``stage``
    (default all): choices as a select box, numbers, flags, text; lists and unset values as JSON;
    labelled in lab units, the option's help and command-line name in the help."""
    from workbench.options import declarations

    options: dict = {}
    for opt in (o for o in declarations(proc) if o.in_stage(stage)):
        name, default = opt.name, opt.default
        wkey = f"{key}.{proc.NAME}.{name}"
        label, hint = lab_label(name), f"{opt.help} `workbench run {proc.NAME} -o {name}=...`".strip()
        if opt.choices is not None and default in opt.choices:
            options[name] = st.selectbox(label, list(opt.choices), index=list(opt.choices).index(default), key=wkey,
                                         help=hint)
        elif isinstance(default, bool):
            options[name] = st.checkbox(label, value=default, key=wkey, help=hint)
        elif isinstance(default, int):
            options[name] = int(st.number_input(label, value=default, step=1, key=wkey, help=hint))
        elif isinstance(default, float):
            options[name] = float(st.number_input(label, value=default, format="%g", key=wkey, help=hint))
        elif isinstance(default, str):
            options[name] = st.text_input(label, value=default, key=wkey, help=hint)
        else:  # None (unset) or a list / dict: JSON text, empty = unset
            text = st.text_input(label, value="" if default is None else json.dumps(default), key=wkey, help=hint,
                                 placeholder="not set (JSON value)" if default is None else None)
            try:
                options[name] = json.loads(text) if text.strip() else None
            except json.JSONDecodeError:
                options[name] = text if default is None else default  # a plain word, e.g. a set id
                if default is not None:
                    st.error(f"option {name}: {text!r} is not valid JSON; using the default")
    return options


def build_sequence(proc: ModuleType, grade: Path, options: Mapping | None = None):
    """The procedure's Sequence for the grade fixture (``proc.sequence(spec, **options)``)."""
    return proc.sequence(load_spec(grade), **dict(options or {}))


def sequence_table(seq: Any) -> pd.DataFrame:
    """One row per expanded step (``Sequence.describe()``: kind, mount, angle °, rate °/s, duration s, setpoint °C)."""
    return pd.DataFrame(seq.describe())


def format_duration(seconds: float) -> str:
    """``3725`` -> ``'1 h 02 min 05 s'``."""
    s = int(round(seconds))
    h, rem = divmod(s, 3600)
    m, sec = divmod(rem, 60)
    return f"{h} h {m:02d} min {sec:02d} s" if h else (f"{m} min {sec:02d} s" if m else f"{sec} s")


def show_sequence(seq: Any) -> None:
    """Steps table and total time of a Sequence, shown before it runs."""
    table = sequence_table(seq)
    c1, c2 = st.columns(2)
    c1.metric("Steps", len(table))
    c2.metric("Total time (rig time)", format_duration(float(seq.duration_s)))
    st.dataframe(table.rename(columns=lab_label), width="stretch", hide_index=True)


# -- background runs -------------------------------------------------------------------
def runs_dir() -> Path:
    """Where dashboard runs write their folders: ``WORKBENCH_RUNS``, else next to a SQLite store, else ./runs."""
    env = os.environ.get("WORKBENCH_RUNS")
    if env:
        return Path(env)
    url = default_url()
    if url.startswith("sqlite:///") and url != "sqlite:///:memory:":
        return Path(url.removeprefix("sqlite:///")).resolve().parent / "runs"
    return Path("runs").resolve()


def default_roots() -> list[Path]:
    """Folders a typed session folder may lie in by default: the runs folder, a SQLite store's folder, the cwd."""
    url = default_url()
    store = [Path(url.removeprefix("sqlite:///")).resolve().parent] \
        if url.startswith("sqlite:///") and url != "sqlite:///:memory:" else []
    return [runs_dir(), *store, Path.cwd()]


def _workbench_cli() -> list[str]:
    script = Path(sys.executable).with_name("workbench")
    return [str(script)] if script.exists() else [sys.executable, "-m", "workbench.cli"]


def start_run(procedure: str, grade: Path, seed: int | None = None, options: Mapping | None = None,
              expected_s: float | None = None, n_steps: int | None = None) -> Path:
    """Start ``workbench run PROC --unit GRADE --rig sim --out DIR`` detached; returns DIR.

    The run survives page reloads (its own process group); ``job.json`` records the command,
    pid and the expected rig time for progress, ``run.log`` its output and ``exit_code`` its
    status once it ends. ``options`` are passed as ``--option key=JSON``.
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
    wrapper = ["sh", "-c", f'"$@" > "{out / LOG_FILE}" 2>&1; echo $? > "{exit_tmp}"; mv "{exit_tmp}" "{out / EXIT_FILE}"',
               "workbench-run", *cmd]
    proc = subprocess.Popen(wrapper, cwd=str(REPO), start_new_session=True, stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env={**os.environ, "COLUMNS": "120"})
    job = {"procedure": procedure, "unit": str(grade), "seed": seed, "options": dict(options or {}),
           "command": cmd, "pid": proc.pid, "started": time.time(), "expected_s": expected_s, "n_steps": n_steps}
    (out / JOB_FILE).write_text(json.dumps(job, indent=1, default=str))
    _CHILDREN[str(out)] = proc
    return out


_CHILDREN: dict[str, subprocess.Popen] = {}  # runs started by this server process (reaped on poll)


@dataclass(frozen=True)
class RunStatus:
    """State of a dashboard run read from its folder.

    ``state`` is ``running``, ``done`` or ``failed``; ``progress`` the recorded fraction of the
    expected rig time (0..1, None when unknown); ``session_dir`` / ``result_dir`` the folders
    holding ``session.json`` / ``result.json`` once they exist; ``log`` the last LOG_LINES of ``run.log``.
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


def _find(folder: Path, name: str) -> Path | None:
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
    """(steps recorded, rig s recorded, steps planned, rig s planned) from a session.json being written.

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


def run_status(folder: Path) -> RunStatus:
    """Status of the run in ``folder`` (see :class:`RunStatus`)."""
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
    session_dir, result_dir = _find(folder, "session.json"), _find(folder, "result.json")
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
    log = ""
    if (folder / LOG_FILE).exists():
        log = "\n".join((folder / LOG_FILE).read_text(errors="replace").splitlines()[-LOG_LINES:])
    return RunStatus(folder, job, state, progress, n_done, n_planned or job.get("n_steps"), session_dir, result_dir,
                     log, code)


_TABLE_CHARS = set("│┃┏┓┗┛┡┩└┘┌┐├┤╭╮╰╯━─═")


def run_summary(log: str) -> str:
    """The lines of a run's log that people read: without the CLI's sequence table and progress bars."""
    keep = [line for line in log.splitlines()
            if line.strip() and line.lstrip()[0] not in _TABLE_CHARS and "━━" not in line
            and not line.strip().startswith("sequence ")]
    return "\n".join(keep)


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


@st.cache_data(show_spinner=False, max_entries=2000)
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


# -- sessions, analysis results, figures -----------------------------------------------
def downsample(df: pd.DataFrame, x: str = "t", max_points: int = 3000) -> pd.DataFrame:
    """Min/max envelope of every numeric column in ``max_points // 2`` buckets of ``x``.

    Keeps the extremes (spikes, steps) visible while a multi-hour session plots in a fraction
    of a second; returns ``df`` unchanged when it is already short.
    """
    if len(df) <= max_points:
        return df
    n_buckets = max(max_points // 2, 1)
    bucket = (np.arange(len(df)) * n_buckets // len(df))
    num = df.select_dtypes("number")
    g = num.groupby(bucket)
    lo, hi = g.min(), g.max()
    lo[x], hi[x] = g[x].first(), g[x].last()
    return pd.concat([lo, hi]).sort_values(x, kind="stable").reset_index(drop=True)


PLOT_UNITS = {"gyro": (["gx", "gy", "gz"], "deg/s"), "accel": (["ax", "ay", "az"], "mg"),
              "mag": (["mx", "my", "mz"], "uT")}  # sample columns per triad and the lab unit they are plotted in
_OTHER_LABELS = {"temp": "temp (°C)", "table_angle": "table_angle (rad)", "table_rate": "table_rate (rad/s)"}


def samples_chart(df: pd.DataFrame, what: str, height: int = 220) -> None:
    """Line chart of a triad (``gyro``/``accel``/``mag``, body frame, lab units) or a column vs ``t`` (s).

    ``df`` should already be downsampled (:func:`downsample`).
    """
    if what in PLOT_UNITS:
        cols, unit = PLOT_UNITS[what]
        if not all(c in df.columns for c in cols):
            return
        plot = pd.DataFrame(lab_array(df[cols], unit), columns=[f"{c} ({units.label(unit)})" for c in cols])
        st.caption(f"{what} (body frame) vs t (s)")
    else:
        plot = df[[what]].rename(columns={what: _OTHER_LABELS.get(what, what)})
        st.caption(f"{what} vs t (s)")
    plot.index = df["t"].to_numpy()
    st.line_chart(plot, height=height)


def session_dirs(procedure: str | None = None) -> dict[str, Path]:
    """Recorded session folders (store sessions and dashboard runs), label -> path, newest first."""
    out: dict[str, Path] = {}
    try:
        rows = store().list_sessions()
    except WorkbenchError as exc:
        show_error(exc, "store")
        rows = []
    for r in rows:
        if procedure is None or r.procedure == procedure:
            out[f"{r.created} · {r.procedure} · {r.serial} · {r.id[:8]}"] = Path(r.path)
    for folder in list_runs():
        d = _find(folder, "session.json")
        if d is not None and d not in out.values():
            try:
                proc = json.loads((folder / JOB_FILE).read_text()).get("procedure")
            except (OSError, json.JSONDecodeError):
                continue
            if procedure is None or proc == procedure:
                out[f"run {folder.name}"] = d
    return out


def session_picker(procedure: str | None = None, key: str = "session") -> Path | None:
    """A select box over recorded sessions (of ``procedure`` if given); a path typed in also works."""
    dirs = session_dirs(procedure)
    choice = st.selectbox("Session", ["(type a folder)", *dirs], index=1 if dirs else 0, key=key)
    if choice == "(type a folder)":
        typed = st.text_input("Session folder", key=f"{key}.typed",
                              help="A folder inside the data roots (WORKBENCH_DATA_ROOTS; default the runs folder, "
                                   "the SQLite store's folder and the working directory).")
        if not typed:
            return None
        try:
            return roots.confined_folder(typed, roots.data_roots(default_roots()))
        except WorkbenchError as exc:
            show_error(exc, "session folder")
            return None
    return dirs[choice]


def folder_mtime(folder: Path) -> float:
    """Newest modification time of the files directly in ``folder`` (a cache key for its contents)."""
    return max((p.stat().st_mtime for p in folder.iterdir()), default=0.0) if folder.is_dir() else 0.0


@st.cache_resource(show_spinner=False, max_entries=8)
def _analyze(procedure: str, folder: str, mtime: float, options_json: str) -> ProcedureResult:
    from workbench.session import load_session

    session = load_session(folder)
    return registry.procedure(procedure).analyze(session, **json.loads(options_json))


def analyze_session(procedure: str, folder: Path, options: Mapping | None = None) -> ProcedureResult:
    """``procedure.analyze(load_session(folder), **options)``, cached per folder version and options.

    Pure (nothing is written or stored); raises WorkbenchError for bad sessions.
    """
    return _analyze(procedure, str(folder), folder_mtime(Path(folder)), json.dumps(dict(options or {}), sort_keys=True))


def stored_result(procedure: str, folder: Path) -> dict | None:
    """The newest stored result (store row: ``result``, ``created``, ``calibration_id``) of the session in ``folder``."""
    try:
        session_id = json.loads((Path(folder) / "session.json").read_text()).get("id")
        rows = store().list_results(procedure)
    except (OSError, json.JSONDecodeError, WorkbenchError):
        return None
    return next((r for r in rows if r["session_id"] == session_id), None)


def show_stored_result(procedure: str, folder: Path, row: dict) -> None:
    """A stored result as it was computed: its summary, warnings, options and the figures drawn then."""
    from workbench.stored import stored_figures, stored_options

    doc = row["result"]
    options = stored_options(folder, procedure, doc)
    st.success(f"Stored result of {row['created']} (as computed then; nothing re-analysed)")
    st.caption("Options it was computed with: " + (", ".join(f"{k} = {json.dumps(v)}" for k, v in options.items())
                                                  if options else "the defaults" if options == {} else "not recorded"))
    summary = [str(s) for s in doc.get("summary", [])]
    if summary:
        st.code("\n".join(summary), language=None)
    for w in doc.get("warnings", []):
        st.warning(str(w))
    with st.expander("result.json"):
        st.json(doc)
    pngs = stored_figures(folder)
    for png in pngs:
        st.image(str(png), caption=png.stem.replace("_", " "))
    if not pngs:
        st.caption("No figures were stored with this result.")


def result_picker(procedure: str, key: str = "result") -> ProcedureResult | None:
    """What an analysis page needs: pick a session of ``procedure``; its stored result is shown as stored.

    Re-analysis of a session with a stored result is an explicit button naming the options it
    uses; a session without one (e.g. a folder typed in) is analysed with the options shown.
    Neither stores anything. Returns the ProcedureResult of that analysis (None while the stored
    result is shown, when there is no session yet or the analysis fails).
    """
    try:
        proc = registry.procedure(procedure)
    except WorkbenchError as exc:
        st.info(f"Procedure {procedure!r} is not installed yet ({exc}).")
        return None
    folder = session_picker(procedure, key=f"{key}.session")
    if folder is None:
        st.info(f"No {procedure} session yet: record one on the Run page or type a session folder.")
        return None
    row = stored_result(procedure, folder)
    if row is not None:
        show_stored_result(procedure, folder, row)
    with st.expander("Re-analyse (stores nothing)" if row is not None else "Analysis options", expanded=False):
        options = option_inputs(proc, key=f"{key}.options", stage="analysis")
        defaults = dict(getattr(proc, "DEFAULTS", {}))
        changed = {k: v for k, v in options.items() if k not in defaults or defaults[k] != v}
        text = "the defaults" + "".join(f", {k} = {json.dumps(v)}" for k, v in changed.items())
        flag = f"{key}.reanalyse.{folder}"
        if row is not None and st.button(f"Re-analyse with: {text}", key=f"{key}.reanalyse"):
            st.session_state[flag] = True
    if row is not None and not st.session_state.get(flag):
        return None  # the stored result is what the page shows
    try:
        with st.spinner(f"Analysing {folder.name} ..."):
            result = analyze_session(procedure, folder, options)
    except Exception as exc:  # noqa: BLE001 - any failure of the analysis is shown, the page stays usable
        show_error(exc, f"{procedure} on {folder}")
        return None
    st.info(f"{'Re-analysis' if row is not None else 'No stored result for this session: analysis'} of "
            f"{folder.name} with {text} (not stored).")
    return result


def show_figures(result: ProcedureResult | Path) -> None:
    """Figures of a result: drawn by ``procedure.figures(result)``, or the PNGs of an output folder."""
    if isinstance(result, ProcedureResult):
        import matplotlib.pyplot as plt

        with guarded(f"figures of {result.procedure}", catch_all=True):
            figs = registry.procedure(result.procedure).figures(result)
            for name, fig in figs.items():
                st.markdown(f"**{name}**")
                st.pyplot(fig, clear_figure=True)
                plt.close(fig)
        return
    pngs = sorted(Path(result).rglob("figures/*.png"))
    for png in pngs:
        st.image(str(png), caption=png.stem)
    if not pngs:
        st.caption("No figures.")


def show_result(result: ProcedureResult | Path, figures: bool = True) -> None:
    """Summary lines (lab units), warnings, calibration id and figures of a result or output folder."""
    if isinstance(result, ProcedureResult):  # a re-analysis: its partial set was never stored
        summary, warnings = list(result.summary), list(result.warnings)
        cal_id = None
    else:
        rpath = next(iter(sorted(Path(result).rglob("result.json"))), None)
        doc = json.loads(rpath.read_text()) if rpath else {}
        summary = [str(s) for s in doc.get("summary", [])]
        warnings, cal_id = [str(w) for w in doc.get("warnings", [])], doc.get("calibration_id")
        if not summary and doc:
            with st.expander("result.json"):
                st.json(doc)
    if summary:
        st.code("\n".join(summary), language=None)
    for w in warnings:
        st.warning(w)
    if cal_id and _in_store(cal_id):  # name a calibration set only when the store holds it
        st.caption(f"Calibration set {cal_id}")
    if figures:
        show_figures(result)


def _in_store(set_id: str) -> bool:
    try:
        store().get_set(set_id)
    except WorkbenchError:
        return False
    return True


def page_link(page: str, label: str) -> None:
    """A link to another dashboard page (``NN_name.py``, with or without its folder); plain text outside app.py."""
    from streamlit.errors import StreamlitAPIException

    try:
        st.page_link(f"dashboard/pages/{Path(page).name}", label=label)
    except StreamlitAPIException:  # the page was run on its own (no st.navigation)
        st.caption(f"{label} ({page})")


def run_panel(name: str, key: str, context: str, check: Callable[[Any], None] | None = None) -> None:
    """Grade, options, sequence preview, seed and a Start button for procedure ``name`` on the simulated rig.

    ``check(spec)`` may show warnings for the chosen grade (e.g. a procedure that does not apply).
    """
    grade = grade_picker(key=f"{key}.grade")
    with guarded(context):
        from workbench import registry

        proc = registry.procedure(name)
        options = option_inputs(proc, key=f"{key}.run")
        if grade is None:
            return
        if check is not None:
            check(load_spec(grade))
        seq = build_sequence(proc, grade, options)
        show_sequence(seq)
        seed = st.number_input("Seed", value=1, step=1, key=f"{key}.seed")
        if st.button("Start run", key=f"{key}.start"):
            folder = start_run(name, grade, int(seed), options, seq.duration_s, len(seq.expand()))
            st.success(f"started: {folder}")
