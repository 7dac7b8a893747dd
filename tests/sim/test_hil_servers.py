"""The loopback servers of the HIL lab (workbench/sim/hil_servers.py): line protocol, faults, ports, templates."""

from __future__ import annotations

import socket

import pytest

from workbench.errors import RigError
from workbench.sim.hil_servers import HOST, LineServer, free_port, port_of, template_regex


def _client(port: int) -> socket.socket:
    c = socket.create_connection((HOST, port), timeout=2.0)
    return c


def _ask(c: socket.socket, line: str) -> bytes:
    c.sendall((line + "\n").encode())
    return c.recv(4096)


@pytest.fixture
def echo():
    faults = {"dev": None}
    srv = LineServer("dev", 0, lambda line: None if line == "quiet" else f"got {line}", faults)
    srv.start()
    yield srv, faults
    srv.stop()


def test_replies_line_by_line_and_stays_silent_on_none(echo):
    srv, _ = echo
    assert srv.port > 0
    with _client(srv.port) as c:
        assert _ask(c, "A") == b"got A\n"
        c.sendall(b"quiet\nB\n")  # no reply to the first, one to the second
        assert c.recv(4096) == b"got B\n"


def test_faults_garbage_silent_and_drop(echo):
    srv, faults = echo
    with _client(srv.port) as c:
        faults["dev"] = "garbage"
        assert _ask(c, "A") == "\x15#?garbage\n".encode()
        faults["dev"] = "silent"
        c.settimeout(0.3)
        c.sendall(b"A\n")
        with pytest.raises(socket.timeout):
            c.recv(4096)
        faults["dev"] = "drop"
        c.settimeout(2.0)
        c.sendall(b"A\n")
        assert c.recv(4096) == b""  # closed
    assert faults["dev"] is None  # a drop fires once...
    with _client(srv.port) as c:  # ... and refuses the next connection too
        c.settimeout(2.0)
        assert c.recv(4096) == b""
    with _client(srv.port) as c:
        assert _ask(c, "C") == b"got C\n"


def test_a_taken_port_is_a_rig_error():
    with socket.socket() as s:
        s.bind((HOST, 0))
        s.listen()
        with pytest.raises(RigError, match=r"hil: dev port \d+"):
            LineServer("dev", s.getsockname()[1], lambda line: line, {})


def test_free_port_is_bindable():
    port = free_port()
    with socket.socket() as s:
        s.bind((HOST, port))


def test_template_regex_captures_the_formatted_numbers():
    rx = template_regex("POS {angle_deg:.4f},{rate_dps:.2f}")
    text = "POS {angle_deg:.4f},{rate_dps:.2f}".format(angle_deg=-12.5, rate_dps=60)
    m = rx.match(text)
    assert m and float(m["angle_deg"]) == -12.5 and float(m["rate_dps"]) == 60.0
    assert rx.match("POS 1,2 extra") is None


def test_port_of_loopback_addresses_only():
    assert port_of("TCPIP0::127.0.0.1::5025::SOCKET", "f") == 5025
    assert port_of("socket://localhost:4001", "f") == 4001
    with pytest.raises(RigError, match=r"hil: table_controller.resource '10.0.0.2:80' is not a 127.0.0.1 address"):
        port_of("10.0.0.2:80", "table_controller.resource")
