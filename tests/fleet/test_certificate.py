"""Certificates: from stored results only, escaped user text, lab fields, PDF without JavaScript or network."""

from __future__ import annotations

import http.server
import json
import shutil
import threading
from pathlib import Path

import numpy as np
import pytest

from workbench.calset import CalibrationSet, Provenance, TriadCalibration, Unit
from workbench.fleet.certificate import print_pdf, render_certificate
from workbench.model import ThermalModel, TriadModel
from workbench.store import Store

CHROMIUM = shutil.which("chromium")
PNG = bytes.fromhex("89504e470d0a1a0a0000000d4948445200000001000000010806000000"
                    "1f15c4890000000d49444154789c6360000002000154a24f5d0000000049454e44ae426082")


def _stored(tmp_path: Path, serial: str, model: str = "industrial_mems") -> tuple[CalibrationSet, Store]:
    """A set whose one session folder holds session.json (rig 'sim') and a stored figure, plus its result."""
    run = tmp_path / "run"
    (run / "figures").mkdir(parents=True)
    (run / "figures" / "gyro_bias_fit.png").write_bytes(PNG)
    (run / "session").mkdir()
    (run / "session" / "session.json").write_text(json.dumps({
        "id": "sess-1", "rig": "sim-turntable", "rig_config": "sim", "created": "2026-01-01T00:00:00Z",
        "options": {"t_min_c": -10.0}, "rig_state": {"air_c": 23.0},
        "steps": [{"temperature_c": -10.0}, {"temperature_c": 50.0}]}))
    th = ThermalModel(23.0, np.array([[0.0, 1e-6, 1e-8]] * 3))
    gyro = TriadCalibration(TriadModel(bias=[1e-4, 0, 0], thermal=th, g_sensitivity=np.eye(3) * 1e-5,
                                       nonlinearity=[1e-6, 0, 0]),
                            {"bias": np.array([1e-6, 1e-6, np.nan]), "nonlinearity": np.full(3, 1e-7)})
    cal = CalibrationSet(Unit(serial, model), {"gyro": gyro},
                         provenance=Provenance(("thermal",), ({"id": "sess-1", "procedure": "thermal",
                                                               "sha256": "ab" * 32, "rig": "sim-turntable"},)))
    store = Store(f"sqlite:///{tmp_path / 'w.db'}")
    store.add_session("sess-1", serial, "industrial_mems", "thermal", str(run / "session"))
    store.add_result("thermal", "sess-1", serial, {"procedure": "thermal", "summary": ["gyro.bias: order 2"],
                                                   "options": {"t_ref_c": 23.0}, "warnings": []}, cal)
    return cal, store


def test_certificate_from_stored_results_with_lab_fields(tmp_path, monkeypatch):
    from workbench import registry

    cal, store = _stored(tmp_path, "IMU-7")
    store.approve(cal.id, "lab lead", "checked")
    # nothing is re-analysed: any analysis call would fail the test
    monkeypatch.setattr(registry, "procedure", lambda name: pytest.fail(f"re-analysed {name}"))
    html = render_certificate(cal, store)
    assert "WB-IMU-7-v1-" + cal.id[:8] in html  # certificate number
    assert "U (k = 2)" in html and "coverage factor k = 2" in html
    # 1e-6 rad/s = 0.2063 °/h: u 0.21, U = 2u = 0.41 °/h
    assert "<td>0.21</td><td>0.41</td><td class=\"l\">°/h</td>" in html
    for text in ("°/h/°C", "°/h/°C²", "°/h/g", "ppm/(°/s)", "rate table (simulated)", "traceability",
                 "approved by <b>lab lead</b>", "setpoints -10.0 .. 50.0 °C", "gyro.bias: order 2", "t_ref_c = 23.0",
                 "page \" counter(page)", "data:image/png;base64"):
        assert text in html, text
    assert "deg/h" not in html and ">uT<" not in html


def test_user_text_is_escaped(tmp_path):
    cal, store = _stored(tmp_path, "U-1", "<script>alert(1)</script>")  # a serial is a safe name; a model free text
    store.approve(cal.id, "<b>mallory</b>", "<img src=x onerror=alert(2)>")
    html = render_certificate(cal, store)
    assert "<script>alert(1)" not in html and "&lt;script&gt;alert(1)&lt;/script&gt;" in html
    assert "<b>mallory</b>" not in html and "<img src=x" not in html


@pytest.mark.skipif(CHROMIUM is None, reason="no chromium on this machine")
def test_pdf_runs_no_script_and_fetches_nothing(tmp_path):
    hits: list[str] = []

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self):  # noqa: N802 - http.server's name
            hits.append(self.path)
            self.send_response(204)
            self.end_headers()

        def log_message(self, *args):
            pass

    server = http.server.HTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    url = f"http://127.0.0.1:{server.server_address[1]}"
    try:
        page = tmp_path / "c.html"
        page.write_text(f"<html><body><p>certificate</p><img src='{url}/img.png'>"
                        f"<script>fetch('{url}/js'); document.body.innerHTML = 'replaced';</script></body></html>")
        pdf = print_pdf(page, tmp_path / "c.pdf", CHROMIUM)
        assert pdf.read_bytes().startswith(b"%PDF")
    finally:
        server.shutdown()
    assert hits == []  # neither the image nor the script's request reached the network


@pytest.mark.skipif(CHROMIUM is None, reason="no chromium on this machine")
def test_the_printing_browser_blocks_javascript(tmp_path):
    """The profile print_pdf uses: a script in the page does not run (the DOM Chromium prints is the static one)."""
    import subprocess

    from workbench.fleet.certificate import chromium_command, new_profile

    page = tmp_path / "s.html"
    page.write_text("<html><body><p id='x'>static</p>"
                    "<script>document.getElementById('x').textContent = 'script ran';</script></body></html>")
    cmd = chromium_command(CHROMIUM, new_profile(tmp_path / "profile"), "--dump-dom", page.as_uri())
    dom = subprocess.run(cmd, capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL).stdout
    assert "<p id=\"x\">static</p>" in dom and "script ran</p>" not in dom


def test_reference_equipment_from_the_rig_file_path_as_from_its_name():
    """Sessions record the rig file's path; reading it with the schema alone gives what load_rig_config gives."""
    from workbench.fleet.certificate import _reference_equipment
    from workbench.rigconfig import RIGS_DIR

    by_name = _reference_equipment([{"id": "a", "rig_config": "sim"}])
    by_path = _reference_equipment([{"id": "b", "rig_config": str(RIGS_DIR / "sim.yaml")}])
    assert by_name == by_path and by_name[0]  # the simulated rig lists its (simulated) reference instruments
