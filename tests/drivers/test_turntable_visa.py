"""Turntable driver (PyVISA, pyvisa-py TCPIP SOCKET) against the loopback table controller."""

from __future__ import annotations

import numpy as np
import pytest

from tests.drivers.conftest import GPIB_BACKEND, hil_yaml
from workbench.sim.hil import free_port
from workbench.drivers.turntable_visa import VisaTurntable
from workbench.errors import RigError


@pytest.fixture
def table(tmp_path, start_lab, closing):
    lab = start_lab(hil_yaml(tmp_path, table_controller={"timeout_s": 0.2, "retries": 1}))
    t = closing(VisaTurntable(lab.config.options["table_controller"]))
    t.open()
    return lab, t


def _wait(t: VisaTurntable, angle: float, timeout_s: float = 5.0) -> float:
    import time

    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        a = t.angle()
        if abs((a - angle + np.pi) % (2 * np.pi) - np.pi) < 1e-5 and abs(t.rate()) < 1e-9:
            return a
        time.sleep(0.02)
    raise AssertionError(f"table did not reach {angle}")


def test_identity_position_rate_and_stop(table):
    lab, t = table
    assert t.identify().startswith("HIL")
    t.goto(np.radians(90.0))
    # read-back quantised to the encoder resolution 1e-4 deg (fixtures/rigs/hil.yaml)
    assert _wait(t, np.radians(90.0)) == pytest.approx(np.radians(90.0), abs=np.radians(1e-4))
    t.spin(np.radians(20.0))
    import time

    time.sleep(0.3)  # 6 s of simulated time at speed 20: the 500 °/s^2 ramp takes 0.04 s
    assert np.degrees(t.rate()) == pytest.approx(20.0, abs=1e-6)
    t.stop()
    time.sleep(0.2)
    assert t.rate() == 0.0
    assert t.interlock() is None


def test_timeout_names_device_and_command(table):
    lab, t = table
    lab.inject("table", "silent")
    with pytest.raises(RigError, match=r"turntable \(TCPIP0::127\.0\.0\.1::\d+::SOCKET\): no answer to 'POS\?' "
                                       r"after 2 tries \(timeout 0\.2 s\)"):
        t.angle()


def test_malformed_reply(table):
    lab, t = table
    lab.inject("table", "garbage")
    with pytest.raises(RigError, match=r"malformed reply .* to 'POS\?' \(expected a number\)"):
        t.angle()


def test_error_reply(table):
    lab, t = table
    with pytest.raises(RigError, match=r"controller error 'ERR -113,Undefined header' in reply to 'BOGUS\?'"):
        t._io("BOGUS?", reply=True)


def test_refused_setpoint(table):
    lab, t = table
    with pytest.raises(RigError, match=r"'RATE:COMM 2000\.00000' refused by the controller: '-222,Data out of range'"):
        t.spin(np.radians(2000.0))  # above the controller's 1000 °/s
    lab.inject("table", "refuse")
    with pytest.raises(RigError, match=r"'POS:COMM 45\.00000' refused"):
        t.goto(np.radians(45.0))


def test_dropped_connection_is_reopened_once(table):
    lab, t = table
    lab.faults["table"] = "drop"  # close this link; the next connection is closed at once as well
    with pytest.raises(RigError, match=r"connection lost during 'POS\?'"):
        t.angle()
    assert t.angle() == pytest.approx(0.0, abs=1e-9)  # the link works again


def test_interlock_reported(table):
    lab, t = table
    lab.inject("table", "interlock")
    assert t.interlock() == "1 (INTERLOCK DOOR OPEN)"


def test_address_that_does_not_answer(closing):
    t = closing(VisaTurntable({"resource": f"TCPIP0::127.0.0.1::{free_port()}::SOCKET", "timeout_s": 0.2}))
    with pytest.raises(RigError, match=r"turntable \(TCPIP0::127\.0\.0\.1::\d+::SOCKET\): cannot open"):
        t.open()


def test_unknown_command_key():
    with pytest.raises(RigError, match=r"unknown command\(s\) spin_up in table_controller.commands"):
        VisaTurntable({"resource": "TCPIP0::127.0.0.1::1::SOCKET", "commands": {"spin_up": "X"}})


def test_position_limits_refused_and_templates_checked(table):
    lab, t = table
    with pytest.raises(RigError, match=r"'POS:RATE 2000\.00000' refused by the controller: '-222,Data out of range'"):
        t.goto(np.radians(45.0), rate=np.radians(2000.0))  # above the controller's 1000 °/s
    t.commands.update(position="MOVE {angle_deg:.4f},{rate_dps:.4f}", position_rate=None, position_accel=None)
    assert t.sends_position_rate and not t.sends_position_accel
    with pytest.raises(RigError, match=r"commands.position 'MOVE \{angle_deg:\.4f\},\{rate_dps:\.4f\}' cannot be "
                                       r"formatted \(KeyError: 'rate_dps'; fields given: \{angle_deg\}\)"):
        t.goto(np.radians(45.0))
    assert [k for _, k, _ in lab.table_log] == ["position_rate"]  # the refused limit only: nothing moved
    assert lab.sim.state.table_angle == 0.0


@pytest.mark.skipif(GPIB_BACKEND, reason="a GPIB backend is installed: the missing-backend error cannot occur")
def test_gpib_resource_without_a_gpib_backend():
    t = VisaTurntable({"resource": "GPIB0::7::INSTR"}, "rig lab: turntable")
    with pytest.raises(RigError) as err:
        t.open()
    assert str(err.value) == ("rig lab: turntable (GPIB0::7::INSTR): cannot open: GPIB resource 'GPIB0::7::INSTR' "
                              "needs a GPIB backend for pyvisa-py and none is installed (install linux-gpib or "
                              "gpib-ctypes)")
