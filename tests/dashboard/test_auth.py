"""The dashboard on a network (issue 16): 127.0.0.1 by default, a token before any page elsewhere,
approvals by the signed-in operator, typed folders inside the data roots."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest
from streamlit import config
from streamlit.testing.v1 import AppTest

from dashboard.auth import TOKEN_ENV, is_loopback, policy, token_matches
from dashboard.roots import ROOTS_ENV, confined_folder, data_roots
from workbench.errors import WorkbenchError

REPO = Path(__file__).resolve().parents[2]
TIMEOUT = 60  # s per script run on a loaded 2-core box


def test_shipped_streamlit_config_binds_loopback_without_statistics():
    cfg = tomllib.loads((REPO / ".streamlit" / "config.toml").read_text())
    assert cfg["server"]["address"] == "127.0.0.1" and cfg["browser"]["gatherUsageStats"] is False
    assert 0 < cfg["server"]["maxUploadSize"] <= 200


@pytest.mark.parametrize("address,token,loopback,rule", [
    ("127.0.0.1", None, True, "open"), ("localhost", None, True, "open"), ("::1", None, True, "open"),
    ("127.0.0.2", None, True, "open"), ("0.0.0.0", None, False, "refuse"), ("", None, False, "refuse"),
    ("192.168.10.5", None, False, "refuse"), ("lab-pc", None, False, "refuse"),
    ("0.0.0.0", "s3cret", False, "sign-in"), ("127.0.0.1", "s3cret", True, "sign-in"),
])
def test_policy(address, token, loopback, rule):
    assert is_loopback(address) is loopback and policy(address, token) == rule


def test_token_comparison():
    assert token_matches("s3cret", "s3cret") and not token_matches("s3cre", "s3cret") and not token_matches("", "x")


@pytest.fixture
def address():
    """Set streamlit's server.address for an in-process AppTest run; restored afterwards."""
    old = config.get_option("server.address")
    yield lambda a: config.set_option("server.address", a)
    config.set_option("server.address", old)


def _app() -> AppTest:
    return AppTest.from_file(str(REPO / "app.py"), default_timeout=TIMEOUT).run()


def test_another_address_without_a_token_serves_nothing(seeded_db, address, monkeypatch):
    monkeypatch.delenv(TOKEN_ENV, raising=False)
    address("0.0.0.0")
    at = _app()
    assert not at.exception and any(TOKEN_ENV in e.value for e in at.error)
    assert not at.metric and "Calibration workbench" not in [t.value for t in at.title]


def test_a_token_is_checked_before_any_page_and_approvals_record_the_operator(seeded_db, address, monkeypatch):
    monkeypatch.setenv(TOKEN_ENV, "s3cret")
    address("0.0.0.0")
    at = _app()
    assert [t.value for t in at.title] == ["Sign in"] and not at.metric
    at.text_input(key="auth.name").input("alice")
    at.text_input(key="auth.token").input("wrong")
    at.button[0].click().run()
    assert any("Sign-in refused" in e.value for e in at.error) and not at.metric
    at.text_input(key="auth.token").input("s3cret")
    at.button[0].click().run()
    assert not at.exception and "Calibration workbench" in [t.value for t in at.title]
    at.switch_page("dashboard/pages/95_calibration_sets.py").run()
    assert not at.exception
    assert not [w for w in at.text_input if w.key == "cal.by"]  # no name to type: the operator is signed in
    at.button(key="cal.approve").click().run()
    assert seeded_db.list_sets()[0].approved_by == "alice"


def test_typed_folders_stay_inside_the_data_roots(tmp_path, monkeypatch):
    (tmp_path / "runs" / "s1").mkdir(parents=True)
    roots = data_roots([tmp_path / "runs"])
    assert confined_folder(str(tmp_path / "runs" / "s1"), roots) == (tmp_path / "runs" / "s1").resolve()
    for bad in ("/etc", str(tmp_path / "runs" / ".." / ".."), "~"):
        with pytest.raises(WorkbenchError, match="outside the data roots"):
            confined_folder(bad, roots)
    (tmp_path / "runs" / "link").symlink_to("/etc")
    with pytest.raises(WorkbenchError, match="outside the data roots"):
        confined_folder(str(tmp_path / "runs" / "link"), roots)
    monkeypatch.setenv(ROOTS_ENV, f"{tmp_path / 'a'}:{tmp_path / 'b'}")
    assert data_roots([tmp_path]) == [(tmp_path / "a").resolve(), (tmp_path / "b").resolve()]


def test_the_session_picker_refuses_a_folder_outside_the_roots(seeded_db, tmp_path, monkeypatch):
    monkeypatch.setenv(ROOTS_ENV, str(tmp_path / "runs"))
    at = AppTest.from_file(str(REPO / "dashboard" / "pages" / "30_sessions.py"), default_timeout=TIMEOUT).run()
    at.selectbox(key="sess.pick").select("(type a folder)").run()
    at.text_input(key="sess.pick.typed").input("/etc").run()
    assert not at.exception and any("outside the data roots" in e.value for e in at.error)
