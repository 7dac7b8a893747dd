"""Sampled Monte Carlo of the land INS: outcomes against the drive's truth, resumable, on Dask."""

from __future__ import annotations

import json

import pytest

from workbench.fleet import land_ins_mc as mc

CASES = [mc.McCase("navigation_grade", r, k, cruise_s=60.0, precalibration=False) for r in (0.0, 1.0) for k in (0, 1)]


def test_outcomes_are_written_and_a_rerun_resumes(tmp_path, monkeypatch):
    seen = []
    out = mc.monte_carlo(CASES[:2], tmp_path, progress=lambda d, n: seen.append((d, n)))
    assert seen[0] == (0, 2) and seen[-1] == (2, 2)
    for o in out:
        # 60 s rest + 60 s cruise of a navigation-grade unit: metres, within 4 sigma of the filter
        assert o["final_error_m"] < 4 * o["final_sigma_m"] + 1.0 and o["distance_m"] > 1000
    assert json.loads(CASES[0].path(tmp_path).read_text())["case"]["rate_dps"] == 0.0

    def boom(case):
        raise AssertionError("a stored outcome must not be recomputed")

    monkeypatch.setattr(mc, "run_one", boom)
    again = mc.monte_carlo(CASES[:2], tmp_path)
    assert again == out
    table = mc.cep_table(out)
    assert table["navigation_grade 0"]["runs"] == 2


@pytest.mark.timeout(300)
def test_runs_on_a_local_dask_cluster(tmp_path):
    from workbench.fleet.batch import cluster_client

    with cluster_client("local", workers=1) as client:
        out = mc.monte_carlo(CASES[2:3], tmp_path, client=client)
    assert len(out) == 1 and CASES[2].path(tmp_path).exists()
