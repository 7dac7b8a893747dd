import json
import os
import shutil
import signal
import subprocess
import sys

import numpy as np

from workbench.session import load_session, recorded_steps

RECORD = """
import sys, types, numpy as np
from pathlib import Path
from workbench.grades import load_spec, draw_unit
from workbench.jobs import record_procedure
from workbench.rigconfig import load_rig_config
from workbench.sequence import Hold, Index, Sequence
proc = types.SimpleNamespace(NAME="demo", TRIADS=("gyro", "accel"), DEFAULTS={},
    sequence=lambda spec: Sequence("demo", [Hold("z-down", dwell_s=20.0), Index(np.pi, 20.0)] * 6))
spec = load_spec("industrial_mems")
# with a second argument k the process kills itself (SIGKILL, no clean-up) once k steps are recorded
kill_after = int(sys.argv[2]) if len(sys.argv) > 2 else None
def progress(i, n, rec):
    if kill_after is not None and i + 1 == kill_after:
        import os, signal
        os.kill(os.getpid(), signal.SIGKILL)
record_procedure(proc, spec, draw_unit(spec, 5), load_rig_config("sim"), 5, Path(sys.argv[1]), progress=progress)
"""


def _recorded_steps(out) -> int:
    try:
        return len(recorded_steps(out, json.loads((out / "session.json").read_text())))
    except (FileNotFoundError, json.JSONDecodeError, KeyError):
        return 0


def test_killed_run_leaves_completed_steps_readable_and_resumes(tmp_path):
    out = tmp_path / "session"
    env = {**os.environ, "PYTHONPATH": os.getcwd()}
    # the recording kills itself right after its 4th step is recorded (step log written): deterministic,
    # no race between the recording and a kill from outside
    p = subprocess.run([sys.executable, "-c", RECORD, str(out), "4"], env=env, timeout=300)
    assert p.returncode == -signal.SIGKILL
    manifest = json.loads((out / "session.json").read_text())
    assert not manifest.get("complete") and _recorded_steps(out) == 4
    done = len(recorded_steps(out, manifest))
    assert done >= 4
    partial = load_session(out, require_complete=False)
    assert len(partial.steps) == done and partial.samples["step"].max() == done - 1
    # a kill between writing a step's part and naming it in the step log leaves an orphan
    # part for the next step; loading ignores it, resuming records that step again
    parts = out / "parts"
    orphan = parts / f"step_{done:05d}.parquet"
    orphan.unlink(missing_ok=True)
    shutil.copy(parts / f"step_{done - 1:05d}.parquet", orphan)
    partial = load_session(out, require_complete=False)
    assert len(partial.steps) == done and partial.samples["step"].max() == done - 1
    from workbench.jobs import resume_procedure

    session = resume_procedure(out)
    assert len(session.steps) == 18 and json.loads((out / "session.json").read_text())["complete"]
    assert not (out / "parts").exists()
    t = session.samples["t"].to_numpy()
    assert (t[1:] > t[:-1]).all()  # time continues across the resume
    # the noise processes continue exactly: the resumed session equals an uninterrupted one
    whole = tmp_path / "whole"
    subprocess.run([sys.executable, "-c", RECORD, str(whole)], env=env, check=True)
    uninterrupted = load_session(whole)
    cols = ["t", "step", "gx", "gy", "gz", "ax", "ay", "az", "temp", "table_angle"]
    assert np.array_equal(session.samples[cols].to_numpy(), uninterrupted.samples[cols].to_numpy())


def test_manifest_written_twice_and_a_torn_log_line_ignored(tmp_path, monkeypatch):
    from workbench import runner
    from workbench.sequence import Hold, Sequence
    from workbench.jobs import simulate

    writes = []
    real = runner.write_manifest
    monkeypatch.setattr(runner, "write_manifest", lambda d, m: (writes.append(len(m["steps"])), real(d, m)))
    seq = Sequence("demo", [Hold("z-down", dwell_s=2.0), Hold("x-up", dwell_s=2.0), Hold("y-up", dwell_s=2.0)])
    out = tmp_path / "s"
    session, _ = simulate(seq, "industrial_mems", 3, out_dir=out)
    assert writes == [0, 3]  # the plan, then the complete session: not once per step
    assert not (out / "steps.jsonl").exists() and not (out / "parts").exists()
    again = load_session(out)
    assert again.samples.equals(session.samples) and again.samples_sha256() == session.samples_sha256()
    # an interrupted recording: two logged steps and a third line cut short by the kill
    part = tmp_path / "p"
    monkeypatch.setattr(runner.Recording, "finish", lambda self: None)
    simulate(seq, "industrial_mems", 3, out_dir=part)
    lines = (part / "steps.jsonl").read_text().splitlines()
    (part / "steps.jsonl").write_text("\n".join(lines[:2]) + "\n" + lines[2][:40])
    partial = load_session(part, require_complete=False)
    assert [s.index for s in partial.steps] == [0, 1]
    assert partial.samples.equals(session.samples[session.samples["step"].isin([-1, 0, 1]) & (
        session.samples["t"] <= partial.steps[-1].t_end + 1e-9)].reset_index(drop=True))
