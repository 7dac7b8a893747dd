"""Espec-style ASCII chamber driver (pyserial socket:// link) against the loopback chamber controller."""

from __future__ import annotations

import pytest

from tests.drivers.conftest import hil_yaml
from workbench.drivers.chamber_ascii import AsciiChamber
from workbench.sim.hil import free_port
from workbench.errors import RigError


@pytest.fixture
def chamber(tmp_path, start_lab, closing):
    lab = start_lab(hil_yaml(tmp_path, chamber_controller={"timeout_s": 0.2, "retries": 1}))
    c = closing(AsciiChamber(lab.config.options["chamber_controller"]))
    c.open()
    return lab, c


def test_read_and_set(chamber):
    lab, c = chamber
    assert "CHAMBER" in c.identify()
    assert c.temperature() == pytest.approx(23.0, abs=0.01)  # air starts at chamber.initial_c; reply has 0.01 °C
    c.set_setpoint(-10.0)
    assert lab.sim.state.chamber_target_c == -10.0


def test_timeout_names_device_and_command(chamber):
    lab, c = chamber
    lab.inject("chamber", "silent")
    with pytest.raises(RigError, match=r"chamber \(socket://127\.0\.0\.1:\d+\): no answer to 'TEMP\?' after 2 tries "
                                       r"\(timeout 0\.2 s\)"):
        c.temperature()


def test_malformed_reply(chamber):
    lab, c = chamber
    lab.inject("chamber", "garbage")
    with pytest.raises(RigError, match=r"malformed reply '.*garbage' to 'TEMP\?' \(expected a number\)"):
        c.temperature()


def test_refused_setpoint(chamber):
    lab, c = chamber
    # 150 °C is above the controller's 125 °C: Espec answers NA
    with pytest.raises(RigError, match=r"setpoint 'TEMP, S150\.0' refused by the controller: 'NA:DATA OUT OF RANGE'"):
        c.set_setpoint(150.0)
    assert lab.sim.state.chamber_target_c == 23.0


def test_dropped_connection(chamber):
    lab, c = chamber
    lab.inject("chamber", "drop")  # the link and the immediate reconnection are both closed
    with pytest.raises(RigError, match=r"connection lost during 'TEMP\?'"):
        c.temperature()
    assert c.temperature() == pytest.approx(23.0, abs=0.01)  # and it reconnects on the next command


def test_error_string_reply(chamber):
    lab, c = chamber
    c.commands["identify"] = "BOGUS?"
    with pytest.raises(RigError, match=r"controller error 'NA:COMMAND ERROR' in reply to 'BOGUS\?'"):
        c.identify()


def test_address_that_does_not_answer(closing):
    c = closing(AsciiChamber({"address": f"socket://127.0.0.1:{free_port()}", "timeout_s": 0.2}))
    with pytest.raises(RigError, match=r"chamber \(socket://127\.0\.0\.1:\d+\): cannot connect"):
        c.open()


def test_missing_address():
    with pytest.raises(RigError, match=r"missing field 'chamber_controller.address'"):
        AsciiChamber({"driver": "ascii"})
