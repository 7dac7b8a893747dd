"""Line links to lab controllers (workbench/drivers/transport.py) against a loopback line server."""

from __future__ import annotations

import pytest

from workbench.drivers.transport import LineTransport, reply_number, serial_url, short_error
from workbench.errors import RigError
from workbench.sim.hil_servers import LineServer, free_port


@pytest.fixture
def server():
    faults = {"dev": None}
    seen: list[str] = []

    def respond(line: str) -> str | None:
        seen.append(line)
        return None if line.startswith("SET") else f"ECHO {line}"

    srv = LineServer("dev", 0, respond, faults, read_termination="\r\n", write_termination="\r\n")
    srv.start()
    yield srv, faults, seen
    srv.stop()


def _link(srv, **kw) -> LineTransport:
    return LineTransport("chamber test", f"tcp://127.0.0.1:{srv.port}", **{"timeout_s": 0.3, "retries": 1, **kw})


def test_query_and_send(server):
    srv, _, seen = server
    link = _link(srv)
    try:
        assert link.query("TEMP?") == "ECHO TEMP?"
        link.send("SET 25")
        assert link.query("MODE?") == "ECHO MODE?"
    finally:
        link.close()
    assert seen == ["TEMP?", "SET 25", "MODE?"]


def test_silence_is_retried_then_one_line_error(server):
    srv, faults, seen = server
    link = _link(srv)
    faults["dev"] = "silent"
    try:
        with pytest.raises(RigError, match=r"chamber test \(tcp://127.0.0.1:\d+\): no answer to 'TEMP\?' after 2 tries "
                                           r"\(timeout 0.3 s\)"):
            link.query("TEMP?")
    finally:
        link.close()
    assert seen.count("TEMP?") == 2  # the first try and one retry


def test_dropped_link_is_reopened_once(server):
    srv, faults, _ = server
    link = _link(srv)
    try:
        assert link.query("A") == "ECHO A"
        faults["dev"] = "drop"  # the server closes the link on the next line and refuses one connection
        with pytest.raises(RigError, match="chamber test .*'B'"):
            link.query("B")
        assert link.query("C") == "ECHO C"  # the server accepts again: the link recovers
    finally:
        link.close()


def test_unreachable_address_names_the_device():
    link = LineTransport("table x", f"tcp://127.0.0.1:{free_port()}", timeout_s=0.2)
    with pytest.raises(RigError, match=r"table x \(tcp://127.0.0.1:\d+\): cannot connect"):
        link.query("X")


def test_reply_numbers_and_urls():
    assert serial_url("tcp://h:1") == "socket://h:1" and serial_url("/dev/ttyUSB0") == "/dev/ttyUSB0"
    assert reply_number("w", "c", " 23.5 ") == 23.5
    assert reply_number("w", "c", "OK,12.25,x", field=1) == 12.25
    with pytest.raises(RigError, match=r"w: malformed reply 'OK' to 'c' \(expected at least 2"):
        reply_number("w", "c", "OK", field=1)
    with pytest.raises(RigError, match="expected a number"):
        reply_number("w", "c", "abc")
    with pytest.raises(RigError, match="not a finite number"):
        reply_number("w", "c", "nan")
    assert short_error(ValueError("first\nsecond")) == "first" and short_error(ValueError()) == "ValueError"
