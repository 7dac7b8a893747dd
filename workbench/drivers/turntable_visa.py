"""Rate-table driver over PyVISA; the command strings come from the rig configuration.

One driver serves SCPI-style motion controllers (ACUTROL-like over GPIB or Ethernet, Ideal
Aerosmith-style ASCII over RS-232 as a VISA ``ASRL`` resource): the configuration's
``table_controller.commands`` gives each command as a Python format string with the fields
``{angle_deg}``, ``{rate_dps}``, ``{accel_dps2}`` and ``{mount}`` (nine comma-separated
numbers, row-major).
The pure-Python ``pyvisa-py`` backend (``visa_library: "@py"``) needs no vendor VISA; a
``TCPIP0::host::port::SOCKET`` resource talks to a plain TCP server. A ``GPIB...`` resource
needs a GPIB backend for pyvisa-py (linux-gpib or gpib-ctypes); without one, :meth:`open`
says so in one line.

A position move carries its rate (and acceleration) limit when the command set has a way to
send it: the ``position_rate`` / ``position_accel`` commands (position-mode limits, sent
before the ``position`` command), or ``{rate_dps}`` / ``{accel_dps2}`` fields in the
``position`` command itself (``"MOVE {angle_deg:.4f},{rate_dps:.4f}"``);
:attr:`VisaTurntable.sends_position_rate` tells which. An absolute move takes the controller's
way round (usually the shortest); with a ``position_relative`` command (field ``{delta_deg}``,
signed) an index turns by its angle in its direction (:meth:`VisaTurntable.turn_by`).

Every setting command is followed by the ``error`` query (when configured): a reply not
matching ``replies.no_error`` is a refused setpoint. Any reply matching
``replies.error_reply`` is a controller error. Timeouts are retried ``retries`` times; a
dropped link is reopened once. Failures are :class:`RigError` naming the table, its
resource and the command. SI at the interface (rad, rad/s), degrees on the wire.
"""

from __future__ import annotations

import importlib.util
import re
import socket
import string
from collections.abc import Mapping

import numpy as np
import pyvisa
from pyvisa.constants import StatusCode

from workbench.angles import wrap_2pi
from workbench.drivers.transport import reopen_once, reply_number, short_error
from workbench.errors import RigError

DEFAULT_COMMANDS = {
    "identify": "*IDN?",
    "position": "POS:COMM {angle_deg:.5f}",  # position mode: go to an absolute angle
    "position_rate": None,  # position-mode rate limit, sent before `position`: "POS:RATE {rate_dps:.5f}"
    "position_accel": None,  # position-mode acceleration limit, sent before `position`: "POS:ACC {accel_dps2:.5f}"
    "position_relative": None,  # a signed relative move (an index turns the way the sequence says): "POS:INCR {delta_deg:.5f}"
    "rate": "RATE:COMM {rate_dps:.5f}",  # rate mode: turn at a constant rate
    "stop": "STOP",  # decelerate to rest and hold
    "read_angle": "POS?",  # reply: degrees
    "read_rate": "RATE?",  # reply: degrees per second
    "status": "STAT?",
    "interlock": "INTL?",  # reply matching replies.interlock_clear when clear
    "error": "SYST:ERR?",  # reply matching replies.no_error when the last command was accepted
    "mount": None,  # motorised fixture / HIL only: "FIXT:MOUNT {mount}"
}
DEFAULT_POSITIONING_RATE = np.radians(60.0)  # rad/s: moves between steps, as on the simulated rig (sim/rig.py)
GPIB_BACKENDS = ("gpib", "gpib_ctypes")  # modules pyvisa-py uses for GPIB: linux-gpib, gpib-ctypes
DEFAULT_REPLIES = {"error_reply": r"^(ERR|ERROR|\?|NAK)", "no_error": r"^\+?0\b", "interlock_clear": r"^0$"}


class VisaTurntable:
    """A single-axis rate table behind a VISA resource, configured by ``table_controller``."""

    def __init__(self, settings: Mapping, name: str = "turntable") -> None:
        if "resource" not in settings:
            raise RigError(f"{name}: missing field 'table_controller.resource'")
        self.resource = str(settings["resource"])
        self.where = f"{name} ({self.resource})"
        self.library = str(settings.get("visa_library", "@py"))
        self.timeout_s = float(settings.get("timeout_s", 1.0))
        self.retries = int(settings.get("retries", 2))
        self.read_termination = str(settings.get("read_termination", "\n"))
        self.write_termination = str(settings.get("write_termination", "\n"))
        unknown = set(settings.get("commands", {}) or {}) - set(DEFAULT_COMMANDS)
        if unknown:
            raise RigError(f"{name}: unknown command(s) {', '.join(sorted(unknown))} in table_controller.commands "
                           f"(known: {', '.join(DEFAULT_COMMANDS)})")
        self.commands = {**DEFAULT_COMMANDS, **(settings.get("commands") or {})}
        replies = {**DEFAULT_REPLIES, **(settings.get("replies") or {})}
        self._error_reply = re.compile(replies["error_reply"])
        self._no_error = re.compile(replies["no_error"])
        self._clear = re.compile(replies["interlock_clear"])
        self._rm = None
        self._inst = None

    # -- link -------------------------------------------------------------------------
    def open(self) -> None:
        """Open the VISA resource; RigError if it does not answer or pyvisa-py has no backend for it."""
        self.close()
        if (self.resource.upper().startswith("GPIB") and self.library == "@py"
                and not any(importlib.util.find_spec(m) for m in GPIB_BACKENDS)):
            raise RigError(f"{self.where}: cannot open: GPIB resource {self.resource!r} needs a GPIB backend for "
                           f"pyvisa-py and none is installed (install linux-gpib or gpib-ctypes)")
        try:
            self._rm = pyvisa.ResourceManager(self.library)
            self._inst = self._rm.open_resource(self.resource, timeout=int(self.timeout_s * 1000),
                                                read_termination=self.read_termination,
                                                write_termination=self.write_termination)
        except (pyvisa.errors.Error, OSError, ValueError) as exc:
            self.close()
            raise RigError(f"{self.where}: cannot open ({short_error(exc)})") from None
        if self._peer_closed():  # pyvisa-py opens a TCP resource even when the connection was refused
            self.close()
            raise RigError(f"{self.where}: cannot open (connection refused or closed by the controller)")

    def close(self) -> None:
        """Release the resource (idempotent)."""
        for obj in (self._inst, self._rm):
            if obj is not None:
                try:
                    obj.close()
                except (pyvisa.errors.Error, OSError):
                    pass
        self._inst = self._rm = None

    def _command(self, key: str, **fields) -> str:
        template = self.commands.get(key)
        if not template:
            raise RigError(f"{self.where}: no '{key}' command in table_controller.commands")
        try:
            return template.format(**{k: v for k, v in fields.items() if v is not None})
        except (KeyError, IndexError, ValueError, TypeError) as exc:
            given = ", ".join(f"{{{k}}}" for k, v in fields.items() if v is not None) or "none"
            raise RigError(f"{self.where}: table_controller.commands.{key} {template!r} cannot be formatted "
                           f"({type(exc).__name__}: {exc}; fields given: {given})") from None

    def _uses(self, key: str, field: str) -> bool:
        """Whether the configured command ``key`` has the format field ``field``."""
        template = self.commands.get(key) or ""
        return any(name == field for _, name, _, _ in string.Formatter().parse(template) if name is not None)

    @property
    def sends_position_rate(self) -> bool:
        """Whether a position move can carry a rate limit (``position_rate`` or ``{rate_dps}`` in ``position``)."""
        return bool(self.commands.get("position_rate")) or self._uses("position", "rate_dps")

    @property
    def sends_position_accel(self) -> bool:
        """Whether a position move can carry an acceleration limit (``position_accel`` or ``{accel_dps2}``)."""
        return bool(self.commands.get("position_accel")) or self._uses("position", "accel_dps2")

    @property
    def turns_relative(self) -> bool:
        """Whether the command set has a signed relative move (``position_relative``)."""
        return bool(self.commands.get("position_relative"))

    def position_commands(self, angle: float, rate: float | None = None, accel: float | None = None,
                          relative: bool = False) -> list[str]:
        """The command strings of :meth:`goto` (``relative``: of :meth:`turn_by`, ``angle`` the signed
        turn) in the order they are sent (checks the templates, sends nothing)."""
        f = {"rate_dps": None if rate is None else float(np.degrees(abs(rate))),
             "accel_dps2": None if accel is None else float(np.degrees(abs(accel)))}
        out = []
        if f["rate_dps"] is not None and self.commands.get("position_rate"):
            out.append(self._command("position_rate", rate_dps=f["rate_dps"]))
        if f["accel_dps2"] is not None and self.commands.get("position_accel"):
            out.append(self._command("position_accel", accel_dps2=f["accel_dps2"]))
        if relative:
            return out + [self._command("position_relative", delta_deg=float(np.degrees(angle)), **f)]
        return out + [self._command("position", angle_deg=float(np.degrees(wrap_2pi(angle))), **f)]

    def _io(self, command: str, reply: bool) -> str:
        tries, reopened = 0, False
        while True:
            try:
                if self._inst is None:
                    self.open()
                if not reply:
                    self._inst.write(command)
                    return ""
                answer = self._inst.query(command).strip()
            except pyvisa.errors.VisaIOError as exc:
                if exc.error_code == StatusCode.error_timeout and not self._peer_closed():
                    tries += 1
                    if tries > self.retries:
                        raise RigError(f"{self.where}: no answer to {command!r} after {tries} tries "
                                       f"(timeout {self.timeout_s:g} s)") from None
                    continue
                reopen_once(self, command, exc, reopened)
                reopened = True
                continue
            except (pyvisa.errors.Error, OSError) as exc:
                self.close()
                raise RigError(f"{self.where}: connection lost during {command!r} ({short_error(exc)})") from None
            if self._error_reply.search(answer):
                raise RigError(f"{self.where}: controller error {answer!r} in reply to {command!r}")
            return answer

    def _peer_closed(self) -> bool:
        """Whether the controller closed a TCP link (pyvisa-py reports that as a timeout)."""
        try:
            sock = self._inst.visalib.sessions[self._inst.session].interface
            return sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b""
        except BlockingIOError:
            return False
        except (ConnectionError, OSError):
            return True
        except (AttributeError, KeyError, TypeError):  # not a pyvisa-py socket session (GPIB, serial, vendor VISA)
            return False

    def query(self, key: str, **fields) -> str:
        """Send the configured command ``key`` and return its reply."""
        return self._io(self._command(key, **fields), reply=True)

    def _set(self, key: str, **fields) -> None:
        self._send(self._command(key, **fields))

    def _send(self, command: str) -> None:
        """Write a setting command and check the controller accepted it (``error`` query)."""
        self._io(command, reply=False)
        if self.commands.get("error"):
            answer = self.query("error")
            if not self._no_error.search(answer):
                raise RigError(f"{self.where}: {command!r} refused by the controller: {answer!r}")

    # -- table ------------------------------------------------------------------------
    def identify(self) -> str:
        """The controller's identity string."""
        return self.query("identify")

    def angle(self) -> float:
        """Read-back table angle, rad, wrapped to [0, 2 pi)."""
        cmd = self._command("read_angle")
        return wrap_2pi(np.radians(reply_number(self.where, cmd, self.query("read_angle"))))

    def rate(self) -> float:
        """Read-back table rate, rad/s (positive clockwise seen from above)."""
        cmd = self._command("read_rate")
        return float(np.radians(reply_number(self.where, cmd, self.query("read_rate"))))

    def goto(self, angle: float, rate: float | None = None, accel: float | None = None) -> None:
        """Position mode: move to the absolute angle ``angle`` rad.

        ``rate`` (rad/s, magnitude) and ``accel`` (rad/s^2) limit the move where the command set
        can send them (:attr:`sends_position_rate`, :attr:`sends_position_accel`); otherwise the
        controller moves at its own slew rate. A ``position`` command with ``{rate_dps}`` needs ``rate``.
        """
        for command in self.position_commands(angle, rate, accel):
            self._send(command)

    def turn_by(self, delta: float, rate: float | None = None, accel: float | None = None) -> None:
        """Position mode: turn by ``delta`` rad (signed, positive clockwise from above) with the
        ``position_relative`` command; ``rate`` and ``accel`` as in :meth:`goto`."""
        for command in self.position_commands(delta, rate, accel, relative=True):
            self._send(command)

    def spin(self, rate: float) -> None:
        """Rate mode: turn at ``rate`` rad/s."""
        self._set("rate", rate_dps=float(np.degrees(rate)))

    def stop(self) -> None:
        """Decelerate to rest."""
        self._set("stop")

    def mount(self, matrix: np.ndarray) -> None:
        """Set a motorised fixture to the body->table-top rotation ``matrix`` (needs the ``mount`` command)."""
        self._set("mount", mount=",".join(f"{v:.9f}" for v in np.asarray(matrix, float).ravel()))

    def status(self) -> str:
        """The controller's status text."""
        return self.query("status")

    def interlock(self) -> str | None:
        """None when the interlocks are clear, else the controller's interlock reply (and status)."""
        if not self.commands.get("interlock"):
            return None
        answer = self.query("interlock")
        if self._clear.search(answer):
            return None
        status = self.status() if self.commands.get("status") else ""
        return f"{answer}{' (' + status + ')' if status else ''}"
