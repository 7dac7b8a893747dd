"""Climatic-chamber driver for ASCII command sets over a serial port or TCP (Espec-style).

The configuration's ``chamber_controller`` gives the address (``/dev/ttyUSB1``,
``socket://host:port``), the line endings and the commands as format strings::

    identify: "ROM?"              # controller identity
    read: "TEMP?"                 # reply "23.1,23.0,125.0,-55.0": measured, setpoint, upper, lower
    read_field: 0                 # which comma-separated field is the air temperature (°C)
    set: "TEMP, S{setpoint_c:.1f}"  # reply "OK: TEMP, S23.0"
    ok: "^OK"                     # a set reply not matching this is a refused setpoint

Any reply matching ``error_reply`` (Espec answers ``NA:...``) is a controller error.
Failures are :class:`RigError` naming the chamber, its address and the command.
"""

from __future__ import annotations

import re
from collections.abc import Mapping

from workbench.drivers.transport import LineTransport, reply_number
from workbench.errors import RigError

DEFAULTS = {"identify": "ROM?", "read": "TEMP?", "read_field": 0, "set": "TEMP, S{setpoint_c:.1f}",
            "ok": r"^OK", "error_reply": r"^(NA|ERR)"}


class AsciiChamber:
    """A chamber answering line commands; temperatures in °C."""

    def __init__(self, settings: Mapping, name: str = "chamber") -> None:
        if "address" not in settings:
            raise RigError(f"{name}: missing field 'chamber_controller.address'")
        s = {**DEFAULTS, **settings}
        self.link = LineTransport(name, s["address"], float(s.get("timeout_s", 1.0)), int(s.get("retries", 2)),
                                  int(s.get("baudrate", 9600)), s.get("write_termination", "\r\n"),
                                  s.get("read_termination", "\r\n"))
        self.where = self.link.where
        self.commands = {k: s[k] for k in ("identify", "read", "set")}
        self.read_field = None if s["read_field"] is None else int(s["read_field"])
        self._ok = re.compile(s["ok"])
        self._error = re.compile(s["error_reply"])

    def open(self) -> None:
        """Connect; RigError if the address does not answer."""
        self.link.open()

    def close(self) -> None:
        """Release the link."""
        self.link.close()

    def _query(self, command: str) -> str:
        reply = self.link.query(command)
        if self._error.search(reply):
            raise RigError(f"{self.where}: controller error {reply!r} in reply to {command!r}")
        return reply

    def identify(self) -> str:
        """The controller's identity reply."""
        return self._query(self.commands["identify"])

    def temperature(self) -> float:
        """Measured air temperature, °C."""
        cmd = self.commands["read"]
        return reply_number(self.where, cmd, self._query(cmd), self.read_field)

    def set_setpoint(self, setpoint_c: float) -> None:
        """Command the air setpoint ``setpoint_c`` °C; RigError if the controller refuses it."""
        cmd = self.commands["set"].format(setpoint_c=float(setpoint_c))
        reply = self.link.query(cmd)
        if self._error.search(reply) or not self._ok.search(reply):
            raise RigError(f"{self.where}: setpoint {cmd!r} refused by the controller: {reply!r}")
