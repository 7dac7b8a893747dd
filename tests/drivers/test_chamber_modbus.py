"""Modbus TCP chamber driver (pymodbus client) against the loopback pymodbus chamber server."""

from __future__ import annotations

import pytest

from tests.drivers.conftest import hil_yaml
from workbench.drivers.chamber_modbus import ModbusChamber
from workbench.sim.hil import free_port
from workbench.errors import RigError

REGISTERS = {"temperature": {"address": 100, "kind": "input", "scale": 0.1},
             "setpoint": {"address": 300, "kind": "holding", "scale": 0.1}}


@pytest.fixture
def chamber(tmp_path, start_lab, closing):
    lab = start_lab(hil_yaml(tmp_path, "hil_modbus", chamber_controller={"timeout_s": 0.3, "retries": 0}))
    c = closing(ModbusChamber(lab.config.options["chamber_controller"]))
    c.open()
    return lab, c


def test_read_and_set_through_the_register_map(chamber):
    lab, c = chamber
    assert c.temperature() == pytest.approx(23.0, abs=0.05)  # register holds 0.1 °C steps
    c.set_setpoint(-12.5)
    assert lab.sim.state.chamber_target_c == pytest.approx(-12.5)  # signed register -125 * 0.1
    assert c._read("setpoint") == pytest.approx(-12.5)


def test_refused_setpoint(chamber):
    lab, c = chamber
    # 100 °C is above this controller's 85 °C: the server answers with exception 3 (illegal data value)
    with pytest.raises(RigError, match=r"chamber \(modbus 127\.0\.0\.1:\d+\): setpoint 100\.00 °C "
                                       r"\(register setpoint 300 <- 1000\) refused by the controller"):
        c.set_setpoint(100.0)
    assert lab.sim.state.chamber_target_c == 23.0


def test_timeout(chamber):
    lab, c = chamber
    lab.inject("chamber", "silent")  # the server holds the reply for 5 s
    with pytest.raises(RigError, match=r"no valid answer to read of register temperature \(100\)"):
        c.temperature()


def test_dropped_connection(chamber):
    lab, c = chamber
    lab.stop()
    with pytest.raises(RigError, match=r"chamber \(modbus 127\.0\.0\.1:\d+\)"):
        c.temperature()


def test_address_that_does_not_answer(closing):
    c = closing(ModbusChamber({"host": "127.0.0.1", "port": free_port(), "registers": REGISTERS, "timeout_s": 0.2}))
    with pytest.raises(RigError, match=r"chamber \(modbus 127\.0\.0\.1:\d+\): cannot connect"):
        c.open()


def test_register_map_checked():
    with pytest.raises(RigError, match=r"missing field 'chamber_controller.registers.setpoint.address'"):
        ModbusChamber({"host": "127.0.0.1", "registers": {"temperature": {"address": 1}}})
    with pytest.raises(RigError, match=r"registers.temperature.kind 'coil'"):
        ModbusChamber({"host": "127.0.0.1", "registers": {**REGISTERS, "temperature": {"address": 1, "kind": "coil"}}})


def test_malformed_reply(chamber):
    lab, c = chamber
    lab.inject("chamber", "garbage")  # the server's reply PDU is mangled
    with pytest.raises(RigError, match=r"chamber \(modbus 127\.0\.0\.1:\d+\): .*read of register temperature \(100\)"):
        c.temperature()
