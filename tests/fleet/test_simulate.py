"""Simulated fleets (workbench/fleet/simulate.py): one folder per unit, seeds and truths of their own."""

import json

from workbench.fleet.simulate import simulate_fleet
from workbench.session import load_session


def test_two_units_each_with_its_truth_and_session(tmp_path):
    calls = []
    dirs = simulate_fleet("industrial_mems", 2, "multiposition", tmp_path, seed0=7, options={"dwell_s": 2.0},
                          progress=lambda k, n, d: calls.append((k, n, d.name)))
    assert [d.name for d in dirs] == ["industrial_mems-00007", "industrial_mems-00008"]
    truths = [json.loads((d / "truth.json").read_text())["unit"] for d in dirs]
    assert [t["serial"] for t in truths] == [d.name for d in dirs]
    assert truths[0]["gyro"]["model"]["bias"] != truths[1]["gyro"]["model"]["bias"]  # each unit drawn with its own seed
    sessions = [load_session(d) for d in dirs]
    assert all(s.unit.serial == d.name and len(s.steps) == 6 for s, d in zip(sessions, dirs))
    assert [c[:2] for c in calls] == [(1, 2), (2, 2)]
