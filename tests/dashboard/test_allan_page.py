"""The Allan page offers every statistic of the family on the simulated hold."""

from pathlib import Path

from streamlit.testing.v1 import AppTest

PAGE = str(Path(__file__).resolve().parents[2] / "dashboard" / "pages" / "40_allan.py")


def test_allan_page_statistic_selector(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{tmp_path}/w.db")
    at = AppTest.from_file(PAGE, default_timeout=120).run()
    assert not at.exception
    at.number_input(key="allan.minutes").set_value(2.0)
    at.button(key="allan.run").click().run()
    assert not at.exception
    at.selectbox(key="allan.stat").set_value("totdev").run()
    assert not at.exception
    df = at.dataframe[-1].value
    assert "totdev" in df.columns and set(df["column"]) == {"gx", "gy", "gz"}
    assert (df["lo"] <= df["totdev"]).all() and (df["totdev"] <= df["hi"]).all()


def test_allan_page_opens_on_recorded_sessions_when_the_store_has_some(seeded_db, tmp_path):
    from tests.dashboard.conftest import SERIAL, make_session
    from workbench.session import write_session

    at = AppTest.from_file(PAGE, default_timeout=120).run()
    assert at.radio(key="allan.source").value == "Simulated rig"  # nothing recorded yet
    folder = write_session(make_session(), tmp_path / "allan-session")
    seeded_db.add_session("sess-allan", SERIAL, "test-imu", "allan", str(folder), n_steps=2)
    at = AppTest.from_file(PAGE, default_timeout=120).run()
    assert not at.exception
    assert at.radio(key="allan.source").value == "Recorded session"
