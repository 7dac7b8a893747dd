"""AppTest check of the navigation dashboard page (dashboard/pages/90_navigation.py)."""

from __future__ import annotations

from pathlib import Path

from streamlit.testing.v1 import AppTest

PAGE = Path(__file__).resolve().parents[2] / "dashboard" / "pages" / "90_navigation.py"


def test_page_loads_with_an_empty_store(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{tmp_path}/wb.db")
    monkeypatch.setenv("WORKBENCH_RUNS", str(tmp_path / "runs"))
    at = AppTest.from_file(str(PAGE), default_timeout=60).run()
    assert not at.exception
    assert at.selectbox(key="nav.proc").value == "zupt-alignment"
    at.selectbox(key="nav.proc").set_value("ahrs-table").run()
    assert not at.exception
    assert any("No ahrs-table run yet" in i.value for i in at.info)


def test_road_procedures_are_run_from_the_page(tmp_path, monkeypatch):
    """The Run tab shows the drive of each road procedure before it starts (the legs as its sequence)."""
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{tmp_path}/wb.db")
    monkeypatch.setenv("WORKBENCH_RUNS", str(tmp_path / "runs"))
    at = AppTest.from_file(str(PAGE), default_timeout=60).run()
    for name, grade in (("land-ins", "tactical_low_noise"), ("lns-dead-reckoning", "quasi_tactical")):
        at.selectbox(key="nav.proc").set_value(name).run()
        at.selectbox(key="nav.grade").set_value(grade).run()
        assert not at.exception, name
        assert any(b.label == "Start run" for b in at.button), name
        assert any(f"No {name} run yet" in i.value for i in at.info)
