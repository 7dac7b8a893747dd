"""``--resume`` checks the parts on disk: a truncated part is recorded again, not a traceback at the end."""

import json
import types

import numpy as np
import pytest

from workbench.grades import draw_unit, load_spec
from workbench.jobs import record_procedure, resume_procedure
from workbench.rigconfig import load_rig_config
from workbench.sequence import Hold, Index, Sequence
from workbench.session import step_log

SPEC = load_spec("industrial_mems")
PROC = types.SimpleNamespace(NAME="demo", TRIADS=("gyro", "accel"), DEFAULTS={},
                             sequence=lambda spec: Sequence("demo", [Hold("z-down", dwell_s=2.0), Index(np.pi, 30.0)] * 3))


class Stop(Exception):
    """Stands for Ctrl-C after a few steps."""


def _interrupted(out, after: int) -> None:
    def progress(i, n, rec):
        if i + 1 == after:
            raise Stop
    with pytest.raises(Stop):
        record_procedure(PROC, SPEC, draw_unit(SPEC, 5), load_rig_config("sim"), 5, out, progress=progress)


@pytest.mark.parametrize("damage", ["truncate", "garbage", "delete"])
def test_a_damaged_part_is_recorded_again(tmp_path, damage):
    out = tmp_path / "session"
    _interrupted(out, after=4)
    part = out / "parts" / "step_00001.parquet"
    if damage == "truncate":
        part.write_bytes(part.read_bytes()[: part.stat().st_size // 2])
    elif damage == "garbage":
        part.write_bytes(b"not parquet")
    else:
        part.unlink()
    manifest = json.loads((out / "session.json").read_text())
    assert len(step_log(out)) == 4  # four steps recorded before the stop
    n = len(manifest["planned"])
    session = resume_procedure(out)
    assert len(session.steps) == n and json.loads((out / "session.json").read_text())["complete"]
    steps = session.samples["step"].to_numpy()
    assert all((steps == k).any() for k in range(n))  # step 1 (and the ones after it) recorded again
    t = session.samples["t"].to_numpy()
    assert (np.diff(t) > 0).all()
