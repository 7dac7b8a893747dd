"""``workbench db`` (workbench/cli/db.py): the schema revision, the upgrade, and a store that cannot open."""

from workbench.cli import main
from workbench.store import HEAD_REVISION


def test_current_then_upgrade_then_current(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{tmp_path}/w.db")
    assert main(["db", "current"]) == 0
    assert f"revision none (empty); this version needs {HEAD_REVISION}" in capsys.readouterr().out
    assert main(["db", "upgrade"]) == 0
    assert f"upgraded to revision {HEAD_REVISION}" in capsys.readouterr().out
    assert main(["db", "current"]) == 0
    assert f"revision {HEAD_REVISION}; this version needs {HEAD_REVISION}" in capsys.readouterr().out


def test_a_store_that_cannot_open_is_one_line_without_the_password(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{tmp_path}/no/such/folder/w.db")
    assert main(["db", "current"]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot open" in err[0]
    monkeypatch.setenv("WORKBENCH_DB", "postgresql+nosuchdriver://lab:s3cret@127.0.0.1:1/x")
    assert main(["db", "current"]) != 0
    captured = capsys.readouterr()
    assert "s3cret" not in captured.err + captured.out and "***" in captured.err
