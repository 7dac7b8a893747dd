"""``workbench run`` / ``analyze``: the plumbing from the command line to files and the store."""

import json

import pandas as pd
import pytest

from workbench.cli import main
from workbench.store import Store


@pytest.fixture
def db(tmp_path, monkeypatch):
    url = f"sqlite:///{tmp_path}/w.db"
    monkeypatch.setenv("WORKBENCH_DB", url)
    return Store(url)


@pytest.mark.parametrize("args,match", [
    (["run", "wobble"], "unknown procedure 'wobble'"),
    (["run", "multiposition", "--unit", "fixtures/units/nope.yaml"], "nope.yaml"),
    (["run", "multiposition", "--option", "positions=5"], "positions=5"),
    (["analyze", "multiposition", "/no/such/session"], "not a session folder"),
])
def test_bad_input_is_one_line_and_exit_2(db, capsys, args, match):
    assert main(args) == 2
    err = capsys.readouterr().err
    assert match in err
    assert db.list_sets() == [] and db.list_sessions() == []


def test_dry_run_shows_the_sequence_and_records_nothing(db, tmp_path, capsys):
    assert main(["run", "multiposition", "--dry-run", "--option", "positions=24", "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "24 steps" in out and not (tmp_path / "o").exists()


def test_run_then_analyze_the_recorded_session(db, tmp_path, capsys):
    out = tmp_path / "mp"
    assert main(["run", "multiposition", "--seed", "4", "--out", str(out), "--option", "dwell_s=5"]) == 0
    result = json.loads((out / "result.json").read_text())
    assert result["procedure"] == "multiposition" and (out / "figures" / "accel_residuals.png").exists()
    [info] = db.list_sets()
    assert info.procedures == ("multiposition",) and len(db.list_sessions()) == 1
    # the same session analysed again, to a file and not into the store
    cal = tmp_path / "cal.json"
    assert main(["analyze", "multiposition", str(out / "session"), "--out", str(cal), "--no-store"]) == 0
    assert json.loads(cal.read_text())["provenance"]["sessions"][0]["id"] == db.list_sessions()[0].id
    assert len(db.list_sets()) == 1
    # a corrupted copy: refused, naming the file and column; the store is unchanged
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "session.json").write_text((out / "session" / "session.json").read_text())
    df = pd.read_parquet(out / "session" / "samples.parquet")
    df.loc[10, "gy"] = float("nan")
    df.to_parquet(bad / "samples.parquet")
    capsys.readouterr()
    assert main(["analyze", "multiposition", str(bad)]) == 2
    assert "column gy: NaN" in capsys.readouterr().err and len(db.list_sets()) == 1
