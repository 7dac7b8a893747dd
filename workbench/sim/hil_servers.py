"""Loopback servers of the hardware-in-the-loop lab (:mod:`workbench.sim.hil`): the transport, no motion.

:class:`LineServer` (a TCP line server on 127.0.0.1 calling ``respond(line)``, with the faults
``silent``, ``garbage`` and ``drop`` injected per device), the Modbus chamber server
(:class:`ModbusChamberServer`, a pymodbus server with a configured register map, reading and
setting the lab's chamber), :func:`free_port`, :func:`template_regex` (a regex for what a
command template formats) and :func:`port_of` (the port of a 127.0.0.1 address). Only
127.0.0.1 is ever served.
"""

from __future__ import annotations

import asyncio
import re
import socket
import socketserver
import threading
from collections.abc import Callable, Mapping

from workbench.errors import RigError

HOST = "127.0.0.1"


def free_port() -> int:
    """A free TCP port on 127.0.0.1."""
    with socket.socket() as s:
        s.bind((HOST, 0))
        return s.getsockname()[1]


def template_regex(template: str) -> re.Pattern:
    """A regex matching what ``template.format(...)`` produces, numbers captured by field name."""
    out, pos = "", 0
    for m in re.finditer(r"\{(\w+)(?::[^}]*)?\}", template):
        out += re.escape(template[pos:m.start()]) + rf"(?P<{m.group(1)}>[-+0-9.eE,]+)"
        pos = m.end()
    return re.compile("^" + out + re.escape(template[pos:]) + "$")


class _Server(socketserver.ThreadingTCPServer):
    daemon_threads = True
    allow_reuse_address = True
    block_on_close = False


class LineServer:
    """A TCP line server on 127.0.0.1 calling ``respond(line) -> reply | None`` with fault injection."""

    def __init__(self, device: str, port: int, respond: Callable[[str], str | None], faults: dict,
                 read_termination: str = "\n", write_termination: str = "\n") -> None:
        self.device, self.respond, self.faults = device, respond, faults
        self.rterm, self.wterm = read_termination, write_termination
        self.refuse_next = 0
        self._conns: set[socket.socket] = set()
        lab = self

        class Handler(socketserver.BaseRequestHandler):
            def handle(self) -> None:
                lab._serve(self.request)

        try:
            self.server = _Server((HOST, port), Handler)
        except OSError as exc:
            raise RigError(f"hil: {device} port {port}: {exc}") from None
        self.port = self.server.server_address[1]
        self._thread = threading.Thread(target=self.server.serve_forever, kwargs={"poll_interval": 0.05},
                                        name=f"hil-{device}", daemon=True)

    def start(self) -> None:
        """Serve in a daemon thread."""
        self._thread.start()

    def stop(self) -> None:
        """Stop serving and close every connection."""
        self.server.shutdown()
        self.server.server_close()
        self._close_all()
        self._thread.join(timeout=2.0)

    def _close_all(self) -> None:
        for c in list(self._conns):
            try:
                c.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            c.close()
        self._conns.clear()

    def _serve(self, conn: socket.socket) -> None:
        if self.refuse_next > 0:
            self.refuse_next -= 1
            conn.close()
            return
        self._conns.add(conn)
        buf = b""
        term = self.rterm.encode()
        try:
            while True:
                data = conn.recv(4096)
                if not data:
                    return
                buf += data
                while term in buf:
                    line, buf = buf.split(term, 1)
                    fault = self.faults.get(self.device)
                    if fault == "drop":
                        self.faults[self.device] = None
                        self.refuse_next = 1
                        self._close_all()
                        return
                    reply = self.respond(line.decode("ascii", errors="replace").strip())
                    if reply is None or fault == "silent":
                        continue
                    if fault == "garbage":
                        reply = "\x15#?garbage"
                    conn.sendall((reply + self.wterm).encode("ascii"))
        except OSError:
            return
        finally:
            self._conns.discard(conn)


class ModbusChamberServer:
    """A pymodbus TCP server (own thread and event loop) with the configured register map."""

    def __init__(self, lab, settings: Mapping) -> None:
        """``lab``: the :class:`~workbench.sim.hil.HilLab` (its ``faults``, ``sim.state`` and ``_set_chamber``);
        ``settings``: the rig's ``chamber_controller`` (port, registers, device_id)."""
        self.lab, self.port = lab, int(settings["port"])
        regs = settings["registers"]
        self.reg = {k: (int(v["address"]), float(v.get("scale", 1.0))) for k, v in regs.items()}
        self.size = max(a for a, _ in self.reg.values()) + 1
        self.device_id = int(settings.get("device_id", 1))
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="hil-modbus", daemon=True)
        self.server = None

    async def _action(self, function_code, start_address, address, count, registers, values):
        from pymodbus.constants import ExcCodes

        lab = self.lab
        if lab.faults["chamber"] == "silent":
            await asyncio.sleep(5.0)
        temp_addr, temp_scale = self.reg["temperature"]
        sp_addr, sp_scale = self.reg["setpoint"]
        registers[temp_addr - start_address] = int(round(lab.sim.state.air_c / temp_scale)) & 0xFFFF
        if values is None:
            registers[sp_addr - start_address] = int(round(lab.sim.state.chamber_target_c / sp_scale)) & 0xFFFF
            return None
        if address == sp_addr:
            raw = int(values[0])
            raw = raw - 0x10000 if raw >= 0x8000 else raw
            if not lab._set_chamber(raw * sp_scale):
                return ExcCodes.ILLEGAL_VALUE
        return None

    def start(self) -> None:
        """Serve the register map on 127.0.0.1 in the server's own event-loop thread."""
        from pymodbus.server import ModbusTcpServer
        from pymodbus.simulator import DataType, SimData, SimDevice

        device = SimDevice(self.device_id, simdata=[SimData(0, count=self.size, values=0,
                                                            datatype=DataType.REGISTERS)], action=self._action)
        self._thread.start()

        def trace_packet(sending: bool, data: bytes) -> bytes:
            """Replies mangled under the ``garbage`` fault (MBAP header kept, PDU replaced)."""
            if sending and self.lab.faults["chamber"] == "garbage":
                return data[:7] + bytes([0x04, 0x7F]) + b"\xff" * (len(data) - 9)
            return data

        async def serve():
            self.server = ModbusTcpServer(device, address=(HOST, self.port), trace_packet=trace_packet)
            await self.server.serve_forever(background=True)

        asyncio.run_coroutine_threadsafe(serve(), self._loop).result(timeout=5.0)

    def stop(self) -> None:
        """Shut the server down and stop its event loop."""
        if self.server is not None:
            asyncio.run_coroutine_threadsafe(self.server.shutdown(), self._loop).result(timeout=5.0)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=2.0)
        self._loop.close()


def port_of(address: str, field: str) -> int:
    """The port of a 127.0.0.1 / localhost ``address`` (VISA resource or socket URL); RigError naming ``field``."""
    m = re.search(r"(?:127\.0\.0\.1|localhost)(?:::|:)(\d+)", address)
    if not m:
        raise RigError(f"hil: {field} {address!r} is not a 127.0.0.1 address with a port")
    return int(m.group(1))
