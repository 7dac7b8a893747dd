"""AppTest of the land-navigation section of the Navigation page, drawn from a stored result."""

from __future__ import annotations

from pathlib import Path

from streamlit.testing.v1 import AppTest

PAGE = Path(__file__).resolve().parents[2] / "dashboard" / "pages" / "90_navigation.py"


def _lns_result() -> dict:
    stats = {"max": 0.7, "mean": 0.2, "std": 0.1, "rms": 0.25, "one_sigma": 0.3}
    runs = {v: {"error_pct": stats} for v in ("sf_state", "no_sf_state")}
    curve = {"distance_m": [0.0, 1000.0, 2000.0], "pct": [None, 0.5, 0.4]}
    return {"raw": runs, "calibrated": runs, "wrong_bias": runs,
            "seed_tables": {"table_2_8_no_sf_state_pct": {"max": 5.5, "mean": 4.0, "std": 0.9, "rms": 4.2,
                                                          "one_sigma": 4.9},
                            "table_2_9_sf_state_pct": {"max": 1.3, "mean": 0.6, "std": 0.3, "rms": 0.7,
                                                       "one_sigma": 0.9}},
            "series": {"error_pct": {"calibrated/sf_state": curve},
                       "odo_scale": {"calibrated/sf_state": {"t": [0.0, 10.0], "value": [0.0, 0.04]}},
                       "track": {"lat_deg": [40.9, 40.91], "lon_deg": [14.2, 14.21]},
                       "gps": {"lat_deg": [40.9, 40.91], "lon_deg": [14.2, 14.21]}}}


def test_section_shows_a_stored_lns_result_beside_the_seed(tmp_path, monkeypatch):
    from workbench.store import Store

    url = f"sqlite:///{tmp_path}/wb.db"
    monkeypatch.setenv("WORKBENCH_DB", url)
    monkeypatch.setenv("WORKBENCH_RUNS", str(tmp_path / "runs"))
    Store(url).add_result("lns-dead-reckoning", "s1", "quasi_tactical-1", _lns_result(), None)
    at = AppTest.from_file(str(PAGE), default_timeout=60).run()
    assert not at.exception
    table = at.dataframe[-1].value
    assert list(table["run"][:4]) == ["seed (table 2 8 no sf state)", "raw", "calibrated", "wrong_bias"]
    assert table["max"].iloc[0] == 5.5 and table["max"].iloc[2] == 0.7


def test_section_says_when_nothing_is_stored(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{tmp_path}/wb.db")
    monkeypatch.setenv("WORKBENCH_RUNS", str(tmp_path / "runs"))
    at = AppTest.from_file(str(PAGE), default_timeout=60).run()
    assert not at.exception and any("No stored land-navigation result" in i.value for i in at.info)
