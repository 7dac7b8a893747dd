"""``workbench db`` (workbench/cli/db.py): the schema revision, the upgrade, and a store that cannot open."""

import pytest

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


@pytest.mark.parametrize("command", ["current", "upgrade"])
def test_a_store_file_that_is_no_database_is_one_line(tmp_path, monkeypatch, capsys, command):
    not_db = tmp_path / "w.db"
    not_db.write_text("t,gx\n0,1\n")  # upgrade was an OperationalError traceback (100 lines)
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{not_db}")
    assert main(["db", command]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert f"store sqlite:///{not_db}: cannot open" in line and "file is not a database" in line
