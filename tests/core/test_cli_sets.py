import json

import pytest

from tests.core.test_store import a_set
from workbench.cli import main
from workbench.store import Store


@pytest.fixture
def db(tmp_path, monkeypatch):
    url = f"sqlite:///{tmp_path}/w.db"
    monkeypatch.setenv("WORKBENCH_DB", url)
    return url


def test_sets_list_show_diff_export(db, tmp_path, capsys):
    s1, s2 = a_set(bias=0.01), a_set(bias=0.02)
    Store(db).add_set(s1)
    path = s2.save(tmp_path / "s2.json")
    assert main(["sets", "list"]) == 0
    assert main(["sets", "list", "--format", "json"]) == 0
    listing = capsys.readouterr().out
    assert s1.id[:8] in listing and '"serial": "U1"' in listing
    assert main(["sets", "show", s1.id[:8]]) == 0
    shown = capsys.readouterr().out
    assert "bias" in shown and "mg" in shown
    assert main(["sets", "diff", s1.id, str(path)]) == 0
    assert "1 coefficient(s) differ" in capsys.readouterr().out
    out_file = tmp_path / "e.yaml"
    assert main(["sets", "export", str(path), "--format", "yaml", "--out", str(out_file)]) == 0
    assert "workbench-calibration/1" in out_file.read_text()
    capsys.readouterr()
    assert main(["sets", "export", s1.id, "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["id"] == s1.id


@pytest.mark.parametrize("args,match", [
    (["sets", "export", "X", "--format", "nope"], "unknown export format 'nope'"),
    (["sets", "show", "deadbeef"], "not in the store"),
])
def test_errors_are_one_line_with_nonzero_exit(db, capsys, args, match):
    if "nope" in args:
        args[2] = str(a_set().save(Store(db).engine.url.database + ".json"))
    assert main(args) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") <= 2


def test_bad_file_leaves_store_unchanged(db, tmp_path, capsys):
    bad = tmp_path / "bad.json"
    d = a_set().to_dict()
    d["accel"]["bias"] = [1, float("nan"), 2]
    bad.write_text(json.dumps(d).replace("NaN", "NaN"))
    assert main(["sets", "merge", str(bad)]) == 2
    assert "bad.json" in capsys.readouterr().err
    assert Store(db).list_sets() == []
    assert main(["--db", f"sqlite:///{tmp_path}/no/such/dir.db", "sets", "list"]) == 2
