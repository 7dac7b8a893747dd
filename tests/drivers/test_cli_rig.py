"""``workbench rig check`` / ``rig hil`` and ``workbench run --rig`` on the loopback rig."""

from __future__ import annotations

import json

import pytest

from tests.drivers.conftest import GPIB_BACKEND, hil_yaml
from workbench.cli import main


def test_rig_check_queries_without_moving(tmp_path, start_lab, capsys):
    path = hil_yaml(tmp_path)
    lab = start_lab(path)
    assert main(["rig", "check", str(path)]) == 0
    text = capsys.readouterr().out
    assert "HIL,workbench turntable simulator" in text and "HIL ESPEC-STYLE CHAMBER" in text
    assert "connection check (nothing moved)" in text
    assert lab.sim.state.table_angle == 0.0 and lab.sim.state.table_rate == 0.0


def test_rig_check_address_that_does_not_answer(tmp_path, capsys):
    assert main(["rig", "check", str(hil_yaml(tmp_path))]) == 2  # nothing listens on these ports
    err = capsys.readouterr().err
    assert "error: rig hil-acutrol-espec: turntable (TCPIP0::127.0.0.1::" in err and "cannot open" in err


def test_rig_check_unknown_driver(tmp_path, capsys):
    assert main(["rig", "check", str(hil_yaml(tmp_path, driver="acme"))]) == 2
    assert "unknown driver 'acme' (known: sim, real)" in capsys.readouterr().err


def test_rig_hil_serves_for_a_while(tmp_path, capsys):
    assert main(["rig", "hil", str(hil_yaml(tmp_path, "hil_modbus")), "--seconds", "0.3"]) == 0
    text = capsys.readouterr().out
    assert "udp://127.0.0.1:" in text and "modbus 127.0.0.1:" in text and "simulator stopped" in text


def test_run_multiposition_on_the_loopback_rig(tmp_path, start_lab, capsys):
    path = hil_yaml(tmp_path)
    start_lab(path)
    out = tmp_path / "run"
    code = main(["run", "multiposition", "--rig", str(path), "--unit", "industrial_mems", "-o", "dwell_s=2",
                 "--out", str(out), "--no-store"])
    assert code == 0, capsys.readouterr()
    manifest = json.loads((out / "session" / "session.json").read_text())
    assert manifest["complete"] and manifest["rig"] == "hil-acutrol-espec" and len(manifest["steps"]) == 6
    assert (out / "calibration.json").exists()


@pytest.mark.skipif(GPIB_BACKEND, reason="a GPIB backend is installed: the missing-backend error cannot occur")
def test_rig_check_gpib_resource_without_a_gpib_backend(tmp_path, capsys):
    path = hil_yaml(tmp_path, table_controller={"resource": "GPIB0::1::INSTR"})
    assert main(["rig", "check", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("error: rig hil-acutrol-espec: turntable (GPIB0::1::INSTR): cannot open: GPIB resource "
                   "'GPIB0::1::INSTR' needs a GPIB backend for pyvisa-py and none is installed (install linux-gpib "
                   "or gpib-ctypes)")
