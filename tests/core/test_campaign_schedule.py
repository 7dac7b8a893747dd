"""The campaign's schedule (workbench/campaign_schedule.py): a real rig records in order in this process."""

from __future__ import annotations

import os
from types import SimpleNamespace

from workbench.campaign_schedule import run_plan


class _Plan:
    """Two procedures whose steps note the process they ran in; the second waits for the first."""

    def __init__(self, driver: str) -> None:
        self.procs = [SimpleNamespace(NAME="a"), SimpleNamespace(NAME="b")]
        self.cfg = SimpleNamespace(driver=driver)
        self.calls: list[tuple[str, int]] = []

    def name(self, k):
        return self.procs[k].NAME

    def planned_s(self, k):
        return 10.0 - k

    def preload(self):
        pass

    def ready(self, k, earlier):
        return all(r is not None for r in earlier)

    def analysis_options(self, k, earlier):
        return {"after": [r["pid"] for r in earlier]}

    def record(self, k, progress=None):
        self.calls.append(("record", os.getpid()))
        return SimpleNamespace(id=f"s{k}", unit=SimpleNamespace(serial="u", model="m"), path=None, steps=[],
                               samples_sha256=lambda: None)

    def analyse(self, k, session, options):
        return {"pid": os.getpid(), "options": options}

    def draw(self, k, result):
        return {}

    def save(self, k, figures, workers=None):
        pass


def test_a_real_rig_records_one_procedure_after_the_other_here():
    plan = _Plan("visa")
    done = run_plan(plan, workers=2)
    assert plan.calls == [("record", os.getpid())] * 2  # in this process, in order
    assert [r["pid"] for r in done.results] == [os.getpid()] * 2
    assert done.busy_s == []  # no worker processes


def test_the_simulated_rig_runs_in_workers_and_hands_results_on_in_order():
    plan = _Plan("sim")
    done = run_plan(plan, workers=2)
    assert all(r["pid"] != os.getpid() for r in done.results)
    assert done.options[1] == {"after": [done.results[0]["pid"]]}  # b analysed once a was known
    assert set(done.usage[0]) == {"record", "analyse"}
    assert len(done.busy_s) == 2 and sum(done.busy_s) > 0  # each worker's time in jobs, for the balance
