import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from workbench.cli import main
from workbench.fleet import batch
from workbench.fleet.batch import cluster_client, run_batch, store_outcomes
from workbench.fleet.simulate import simulate_fleet
from workbench.errors import WorkbenchError
from workbench.store import Store


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    out = tmp_path_factory.mktemp("fleet")
    return simulate_fleet("industrial_mems", 4, "multiposition", out, seed0=11, options={"dwell_s": 10.0})


def _numbers(outcome):
    """Every number of the result and the set; only the set's id and creation time are per analysis."""
    cal = {k: v for k, v in outcome["calibration"].to_dict().items() if k not in ("id", "created")}
    return {k: v for k, v in outcome["result"].items() if k != "calibration_id"}, cal


def test_batch_on_local_cluster_matches_serial_and_isolates_a_bad_session(fleet, tmp_path, monkeypatch):
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "session.json").write_text("{broken")
    crash = tmp_path / "crash"  # a task that raises out of the work function (as a dead worker does)
    dirs = [fleet[0], fleet[1], bad, crash, fleet[2], fleet[3]]
    serial = run_batch("multiposition", [d for d in dirs if d != crash], None, None)
    real = batch.analyze_one

    def analyze_or_raise(procedure, session_dir, options=None):
        if session_dir.endswith("crash"):
            raise RuntimeError("worker lost")
        return real(procedure, session_dir, options)

    monkeypatch.setattr(batch, "analyze_one", analyze_or_raise)  # shipped to the workers by value
    store = Store(f"sqlite:///{tmp_path}/w.db")
    with cluster_client("local", workers=2) as client:
        assert all(addr.startswith("tcp://127.0.0.1") for addr in client.scheduler_info()["workers"])
        parallel = run_batch("multiposition", dirs, client, store)
    errors = {Path(o["session_dir"]).name: o["error"] for o in parallel.failures}
    assert set(errors) == {"bad", "crash"} and len(parallel.succeeded) == 4
    assert "not valid JSON" in errors["bad"] and errors["crash"] == "RuntimeError: worker lost"
    by_dir = {o["session_dir"]: o for o in serial.succeeded}
    for o in parallel.succeeded:  # the same function on the workers: identical numbers
        assert _numbers(o) == _numbers(by_dir[o["session_dir"]])
    assert len(store.list_results("multiposition")) == 4 and len(store.list_sets()) == 4


def test_store_batch_isolates_a_write_that_fails(fleet, tmp_path):
    """Outcomes written together share one transaction; a set the store refuses rolls it back,
    then each is written alone (session record and result together) so only that one fails and
    nothing of it is stored."""
    outcomes = run_batch("multiposition", fleet[:3], None, None).outcomes
    outcomes[1]["calibration"] = dataclasses.replace(outcomes[1]["calibration"], notes={"x": float("nan")})
    store = Store(f"sqlite:///{tmp_path}/w.db")
    store_outcomes(store, outcomes)
    assert [o["ok"] for o in outcomes] == [True, False, True]
    assert "NaN or infinite value" in outcomes[1]["error"]
    good = {outcomes[0]["session"]["id"], outcomes[2]["session"]["id"]}
    assert {r["session_id"] for r in store.list_results("multiposition")} == good
    assert {s.id for s in store.list_sessions()} == good and len(store.list_sets()) == 2


def test_unreachable_scheduler_is_a_clear_error():
    with pytest.raises(WorkbenchError, match="tcp://127.0.0.1:1 does not answer"):
        with cluster_client("tcp://127.0.0.1:1"):
            pass


def test_cli_batch_stats_and_certificate(fleet, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{tmp_path}/w.db")
    assert main(["batch", "multiposition", *map(str, fleet), "--scheduler", "serial"]) == 0
    assert "4 analysed, 0 failed" in capsys.readouterr().out
    assert main(["sets", "stats", "--grade", "industrial_mems"]) == 0
    table = capsys.readouterr().out
    assert "4 units" in table and "bias" in table
    assert main(["sets", "list", "--format", "json"]) == 0
    listing = json.loads(capsys.readouterr().out)
    assert {"id", "serial", "model", "created", "procedures"} <= set(listing[0])
    # a set without mag or noise blocks: those sections are shown absent, not omitted
    cert = tmp_path / "cert.html"
    assert main(["certificate", listing[0]["id"], "--out", str(cert), "--no-pdf"]) == 0
    html = cert.read_text()
    assert "Absent: this set has no mag calibration" in html and "Absent: no noise characterisation" in html
    assert listing[0]["serial"] in html
    # figures come from what was stored with the result (no re-analysis): batch stores none, and the page says so
    assert "no figures were stored with its result" in html and "data:image/png;base64" not in html


def test_stats_flags_an_outlier():
    from workbench.calset import CalibrationSet, TriadCalibration, Unit
    from workbench.fleet.stats import coefficient_stats
    from workbench.model import TriadModel

    rng = np.random.default_rng(0)
    biases = list(rng.normal(0, 1e-3, 19)) + [0.05]
    sets = [CalibrationSet(Unit(f"U{i}", "g"), {"accel": TriadCalibration(TriadModel(bias=[b, 0, 0]),
                                                                            {"bias": np.full(3, 1e-4)})})
            for i, b in enumerate(biases)]
    row = next(r for r in coefficient_stats(sets) if r.field == "bias" and r.index == (0,))
    assert row.n == 20 and [o[0] for o in row.outliers] == ["U19"]
