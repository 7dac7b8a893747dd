"""One command = one store transaction; the store URL's password never in output (issue 16)."""

import pytest

from tests.cli.test_run_cli import db  # noqa: F401 (fixture: a Store on $WORKBENCH_DB)
from workbench import jobs
from workbench.cli import main
from workbench.errors import StoreError
from workbench.grades import draw_unit, load_spec
from workbench.rigconfig import load_rig_config
from workbench.store import Store, redact_url


class Injected(Exception):
    """The failure injected between two writes of one command."""


def _fail(*args, **kwargs):
    raise Injected("killed between the writes")


def test_analyze_writes_session_result_and_set_together(db, tmp_path, monkeypatch, capsys):
    out = tmp_path / "mp"
    assert main(["run", "multiposition", "--seed", "4", "--out", str(out), "-o", "dwell_s=5", "--no-store"]) == 0
    with monkeypatch.context() as m, pytest.raises(Injected):
        m.setattr(Store, "add_result", _fail)  # after add_session wrote the session row
        main(["analyze", "multiposition", str(out / "session")])
    assert db.list_sessions() == [] and db.list_sets() == [] and db.list_results() == []
    assert main(["analyze", "multiposition", str(out / "session")]) == 0
    assert len(db.list_sessions()) == 1 and len(db.list_sets()) == 1 and len(db.list_results()) == 1


def test_campaign_writes_sessions_results_and_set_together(db, tmp_path, monkeypatch):
    spec = load_spec("industrial_mems")
    monkeypatch.setattr(Store, "add_set", _fail)  # after every session and result row was written
    with pytest.raises(Injected):
        jobs.run_campaign(spec, draw_unit(spec, 2), load_rig_config("sim"), 2, tmp_path / "c", db,
                          only=["multiposition"], options={"multiposition": {"dwell_s": 5.0}})
    assert db.list_sessions() == [] and db.list_results() == [] and db.list_sets() == []


@pytest.mark.parametrize("url,shown", [
    ("postgresql+psycopg://bob:hunter2@127.0.0.1:1/wb", "postgresql+psycopg://bob:***@127.0.0.1:1/wb"),
    ("postgresql://bob:p%40ss@db.lab/wb", "postgresql://bob:***@db.lab/wb"),
    ("sqlite:///w.db", "sqlite:///w.db"),
    ("postgresql://bob@db.lab/wb", "postgresql://bob@db.lab/wb"),
])
def test_redact_url(url, shown):
    assert redact_url(url) == shown


def test_the_password_never_appears_in_output(tmp_path, monkeypatch, capsys):
    url = "postgresql+psycopg://bob:hunter2@127.0.0.1:1/wb"  # nothing listens on port 1
    with pytest.raises(StoreError) as info:
        Store(url)
    assert "hunter2" not in str(info.value) and "bob:***@" in str(info.value)
    for args in (["--db", url, "sets", "list"], ["--db", url, "db", "current"]):
        assert main(args) == 2
        captured = capsys.readouterr()
        assert "hunter2" not in captured.err + captured.out and "***" in captured.err
