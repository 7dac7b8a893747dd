"""Calibration sets page on sets like the campaign's: noise with 95 % intervals, thermal, partial triads."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from streamlit.testing.v1 import AppTest

from tests.dashboard.conftest import SERIAL
from workbench.calset import CalibrationSet, TriadCalibration, Unit
from workbench.model import ThermalModel, TriadModel

PAGE = Path(__file__).resolve().parents[2] / "dashboard" / "pages" / "95_calibration_sets.py"


def _campaign_like(serial: str, bias_y: float, bias_y_sigma: float) -> CalibrationSet:
    th = ThermalModel(23.0, np.array([[0.0, 1e-5, 1e-7]] * 3))
    gyro = TriadCalibration(TriadModel(bias=[1e-4, bias_y, 0.0], thermal=th,
                                       g_sensitivity=np.full((3, 3), 1e-5)),
                            {"bias": np.array([1e-6, bias_y_sigma, np.nan])})
    noise = {"gyro": {"arw": [1e-4, None, 1e-4], "arw_ci95": [[9e-5, 1.1e-4], None, [9e-5, 1.1e-4]]},
             "accel": {"vrw": [7e-4, 8e-4, 8e-4], "vrw_ci95": [[6e-4, 8e-4]] * 3}}
    return CalibrationSet(Unit(serial, "industrial_mems"), {"gyro": gyro}, noise=noise)


def test_noise_block_with_intervals_shows_in_lab_units_and_diff_states_not_observed(seeded_db):
    # v1 estimated gyro y bias (2.7e-3 rad/s ± 1e-6); v2 did not observe it (prior 0, sigma null)
    seeded_db.add_set(_campaign_like("CAMP-1", 2.7e-3, 1e-6))
    seeded_db.add_set(_campaign_like("CAMP-1", 0.0, np.nan))
    at = AppTest.from_file(str(PAGE), default_timeout=60).run()
    at.selectbox(key="cal.unit").select("CAMP-1").run()
    assert not at.exception and not at.error
    assert at.selectbox(key="cal.version").value == 2  # newest of the newly picked unit
    noise = next(d.value for d in at.dataframe if "95 % interval" in d.value.columns)
    arw_y = noise[(noise.term == "arw") & (noise.axis == "y")].iloc[0]
    assert arw_y.value == "not observed" and arw_y.unit == "°/√h"
    coeffs = next(d.value for d in at.dataframe if "coefficient" in d.value.columns and "sigma" in d.value.columns)
    assert {"°/h", "°/h/g", "°/h/°C", "°/h/°C²"} <= set(coeffs.unit)
    diff = at.dataframe[-1].value
    y = diff[diff.coefficient == "bias y"].iloc[0]
    assert y.state == "not observed in B" and np.isnan(y["change (σ)"]) and y.new == "not observed"


def test_switching_unit_opens_the_newest_version(seeded_db):
    for _ in range(3):  # OTHER has versions 1..3, DASH-001 (seeded) 1..2
        seeded_db.add_set(CalibrationSet(Unit("OTHER", "m"), {}))
    at = AppTest.from_file(str(PAGE), default_timeout=60).run()
    assert at.selectbox(key="cal.unit").value == SERIAL
    at.selectbox(key="cal.version").select(1).run()
    at.selectbox(key="cal.unit").select("OTHER").run()
    assert not at.exception
    assert at.selectbox(key="cal.version").value == 3


def test_certificate_keeps_the_html_when_chromium_fails_to_print(seeded_db, monkeypatch):
    # a Chromium that times out (a starved machine) must not take the HTML certificate with it
    from workbench.errors import WorkbenchError
    from workbench.fleet import certificate

    def stuck(html_path, pdf_path, chromium, timeout_s=120.0):
        raise WorkbenchError(f"{pdf_path}: Chromium did not print the certificate within {timeout_s:g} s")

    monkeypatch.setattr(certificate, "find_chromium", lambda: "/usr/bin/chromium")
    monkeypatch.setattr(certificate, "print_pdf", stuck)
    at = AppTest.from_file(str(PAGE), default_timeout=60).run()
    at.button(key="cal.cert").click().run()
    assert not at.exception and not at.error
    downloads = [e for e in at.get("download_button") if e.proto.label.startswith("certificate")]
    assert [e.proto.label for e in downloads] == ["certificate (.html)"]
    notes = [t.value for t in at.text]
    assert any(n.startswith("PDF not printed (") and "within 120 s" in n and n.endswith("HTML only.") for n in notes), notes
