"""The campaign scheduler (workbench/campaign_schedule.py): in parallel workers it gives the same
results, options, session records and files as in order in one process, and a real rig runs in
order in this process.

The plan is a stand-in with the interface of :class:`workbench.jobs.CampaignPlan`: each recording
is seeded random numbers, procedure 0 yields the noise terms that procedures 2 and 3 need (as the
Allan record's B and K feed the static and thermal fits), figures are text files. The reference
is the plain sequential evaluation written in the test (no scheduler involved).
"""

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from workbench.campaign_schedule import run_plan

NEEDS_NOISE = {2, 3}
FIGURES = {0: 1, 1: 0, 2: 4, 3: 2}  # procedure -> number of figures (2 and more split over workers)


@dataclass
class FakeSession:
    id: str
    data: np.ndarray
    recorded_by: int

    @property
    def unit(self):
        return SimpleNamespace(serial=f"SN{self.id}", model="fake")

    @property
    def path(self):
        return Path("/sessions") / self.id

    @property
    def steps(self):
        return [0] * (len(self.data) // 100)

    def samples_sha256(self):
        return hashlib.sha256(self.data.tobytes()).hexdigest()


class FakePlan:
    def __init__(self, out: Path, driver: str = "sim"):
        self.procs = ["allan", "multiposition", "static", "thermal"]
        self.cfg = SimpleNamespace(driver=driver)
        self.out = out
        out.mkdir(parents=True, exist_ok=True)

    def name(self, k):
        return self.procs[k]

    def planned_s(self, k):
        return [30.0, 10.0, 20.0, 40.0][k]

    def record(self, k, progress):
        data = np.random.default_rng(100 + k).normal(size=200 + 100 * k)
        if progress is not None:
            progress(1, 1, None)
        return FakeSession(f"s{k}", data, os.getpid())

    def ready(self, k, earlier):
        return k not in NEEDS_NOISE or earlier[0] is not None

    def analysis_options(self, k, earlier):
        return {"noise": earlier[0]["noise"]} if k in NEEDS_NOISE else {}

    def analyse(self, k, session, options):
        return {"mean": float(session.data.mean()), "noise": float(session.data.std()),
                "used": options.get("noise"), "recorded_by": session.recorded_by}

    def draw(self, k, result):
        return {f"{self.procs[k]}_{i}": f"{self.procs[k]} {i} {result['mean']:.17g} {result['used']}"
                for i in range(FIGURES[k])}

    def save(self, k, figures, workers=None):
        for name, text in figures.items():
            (self.out / f"{name}.txt").write_text(text)


def _reference(plan: FakePlan):
    """Plain in-order evaluation: record, options from the earlier results, analyse, save."""
    results, options = [], {}
    for k in range(len(plan.procs)):
        session = plan.record(k, None)
        options[k] = plan.analysis_options(k, results)
        results.append(plan.analyse(k, session, options[k]))
        plan.save(k, plan.draw(k, results[k]))
    return results, options


def _files(folder: Path) -> dict:
    return {p.name: p.read_text() for p in sorted(folder.iterdir())}


def _strip(results):
    return [{k: v for k, v in r.items() if k != "recorded_by"} for r in results]


@pytest.mark.parametrize("workers", [1, 2])
def test_schedule_gives_the_in_order_results_options_and_files(tmp_path, workers):
    ref_results, ref_options = _reference(FakePlan(tmp_path / "ref"))
    done = run_plan(FakePlan(tmp_path / "run"), workers=workers)
    assert _strip(done.results) == _strip(ref_results)
    assert done.options == ref_options
    assert all(r["used"] == ref_results[0]["noise"] for k, r in enumerate(done.results) if k in NEEDS_NOISE)
    assert _files(tmp_path / "run") == _files(tmp_path / "ref")
    assert len(_files(tmp_path / "run")) == sum(FIGURES.values())
    for k, info in enumerate(done.sessions):
        assert info.id == f"s{k}" and info.serial == f"SNs{k}" and info.n_steps == (200 + 100 * k) // 100
        assert info.sha256 == hashlib.sha256(np.random.default_rng(100 + k).normal(size=200 + 100 * k).tobytes()).hexdigest()
    for k in range(4):
        assert {"record", "analyse", "figures"} <= set(done.usage[k]) or FIGURES[k] == 0
    if workers == 2:  # the recordings ran in the worker processes, not here
        assert all(r["recorded_by"] != os.getpid() for r in done.results)


def test_a_real_rig_runs_in_order_in_this_process(tmp_path):
    done = run_plan(FakePlan(tmp_path / "run", driver="rig"), workers=4)
    assert all(r["recorded_by"] == os.getpid() for r in done.results)
    ref_results, _ = _reference(FakePlan(tmp_path / "ref"))
    assert _strip(done.results) == _strip(ref_results)
