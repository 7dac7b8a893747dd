"""The dashboard page ``40_allan.py``: a short simulated run shows the figure and the terms table."""

from pathlib import Path

from streamlit.testing.v1 import AppTest

PAGE = Path(__file__).resolve().parents[2] / "dashboard" / "pages" / "40_allan.py"


def test_page_runs_simulation_and_shows_terms(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{tmp_path / 'wb.db'}")
    at = AppTest.from_file(str(PAGE), default_timeout=120).run()
    assert not at.exception
    at.selectbox(key="allan.grade").select("industrial_mems")
    at.number_input(key="allan.minutes").set_value(5.0)
    at.button(key="allan.run").click().run()
    assert not at.exception and not at.error
    table = at.dataframe[0].value
    assert set(table["triad"]) == {"gyro", "accel"}
    white = table[(table.triad == "gyro") & (table.term == "white")]
    assert all("°/√h" in v for v in white["value"])
