"""The fleet page: per-grade coefficient statistics with an outlier flagged, and an empty store."""

from pathlib import Path

import numpy as np
from streamlit.testing.v1 import AppTest

from workbench.calset import CalibrationSet, TriadCalibration, Unit
from workbench.model import TriadModel
from workbench.store import Store

PAGE = str(Path(__file__).resolve().parents[2] / "dashboard" / "pages" / "97_fleet.py")


def test_fleet_page_flags_the_outlier_unit(tmp_path, monkeypatch):
    url = f"sqlite:///{tmp_path}/w.db"
    monkeypatch.setenv("WORKBENCH_DB", url)
    store = Store(url)
    rng = np.random.default_rng(1)
    for i, b in enumerate([*rng.normal(0, 1e-3, 9), 0.05]):  # m/s^2: the last unit is 5 mg off
        tc = TriadCalibration(TriadModel(bias=[b, 0, 0]), {"bias": np.full(3, 1e-4)})
        store.add_set(CalibrationSet(Unit(f"F{i}", "grade-a"), {"accel": tc}))
    at = AppTest.from_file(PAGE, default_timeout=60).run()
    assert not at.exception
    assert at.metric[0].value == "10"
    df = at.dataframe[0].value
    row = df[(df["field"] == "bias") & (df["index"] == "(0,)")].iloc[0]
    assert row["unit"] == "mg" and "F9" in row["outliers"]


def test_fleet_page_on_an_empty_store(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{tmp_path}/w.db")
    at = AppTest.from_file(PAGE, default_timeout=60).run()
    assert not at.exception and "No units" in at.info[0].value
