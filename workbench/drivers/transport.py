"""Line-oriented request/reply links to lab controllers over a serial port or TCP.

:class:`LineTransport` opens any address pyserial understands (``/dev/ttyUSB0``, ``COM3``,
``socket://host:port``; ``tcp://host:port`` is accepted as a synonym of ``socket://``),
sends a command line and reads one reply line, with a timeout per try, a number of retries
and one reconnection when the link drops. Every failure is a :class:`RigError` naming the
device, its address and the command.
"""

from __future__ import annotations

import serial

from workbench.errors import RigError


def serial_url(address: str) -> str:
    """The pyserial URL of an address (``tcp://h:p`` -> ``socket://h:p``; others unchanged)."""
    return "socket://" + address[len("tcp://"):] if address.startswith("tcp://") else address


class LineTransport:
    """A command/reply line link (serial or TCP) with timeouts, retries and reconnection.

    Parameters
    ----------
    device : name used in error messages (e.g. ``"chamber espec"``)
    address : pyserial URL or port name (see the module docstring)
    timeout_s : time to wait for one reply line, s
    retries : further tries after a timeout
    baudrate : serial ports only
    write_termination, read_termination : line endings sent and expected
    """

    def __init__(self, device: str, address: str, timeout_s: float = 1.0, retries: int = 2, baudrate: int = 9600,
                 write_termination: str = "\r\n", read_termination: str = "\r\n", encoding: str = "ascii") -> None:
        self.device, self.address = device, str(address)
        self.timeout_s, self.retries, self.baudrate = float(timeout_s), int(retries), int(baudrate)
        self.wterm, self.rterm, self.encoding = write_termination, read_termination.encode(encoding), encoding
        self._port = None

    @property
    def where(self) -> str:
        """``device (address)`` for messages."""
        return f"{self.device} ({self.address})"

    def open(self) -> None:
        """Connect; RigError if the address does not answer."""
        self.close()
        try:
            self._port = serial.serial_for_url(serial_url(self.address), baudrate=self.baudrate,
                                               timeout=self.timeout_s, write_timeout=self.timeout_s)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise RigError(f"{self.where}: cannot connect ({short_error(exc)})") from None

    def close(self) -> None:
        """Release the port (idempotent)."""
        if self._port is not None:
            try:
                self._port.close()
            except (serial.SerialException, OSError):
                pass
            self._port = None

    def query(self, command: str) -> str:
        """Send ``command`` and return the reply line (stripped); retries on timeout."""
        return self._exchange(command, reply=True)

    def send(self, command: str) -> None:
        """Send ``command`` without waiting for a reply."""
        self._exchange(command, reply=False)

    def _exchange(self, command: str, reply: bool) -> str:
        reconnected = False
        tries = 0
        while True:
            try:
                if self._port is None:
                    self.open()
                self._port.reset_input_buffer()  # drop late replies to an earlier, timed-out query
                self._port.write((command + self.wterm).encode(self.encoding))
                if not reply:
                    return ""
                raw = self._port.read_until(self.rterm)
            except (serial.SerialException, OSError) as exc:
                reopen_once(self, command, exc, reconnected)
                reconnected = True
                continue
            if raw.endswith(self.rterm):
                return raw[:-len(self.rterm)].decode(self.encoding, errors="replace").strip()
            tries += 1
            if tries > self.retries:
                got = f"; partial reply {raw[:40]!r}" if raw else ""
                raise RigError(f"{self.where}: no answer to {command!r} after {tries} tries "
                               f"(timeout {self.timeout_s:g} s{got})")


def reopen_once(link, command: str, exc: BaseException, already_reopened: bool) -> None:
    """After ``link`` lost its connection during ``command``: close it and reopen it once.

    A second loss in the same exchange, or a reopen that fails, raises RigError naming the
    device, the command and the cause. ``link`` has ``where``, ``open()`` and ``close()``.
    """
    link.close()
    lost = f"{link.where}: connection lost during {command!r} ({short_error(exc)})"
    if already_reopened:
        raise RigError(lost) from None
    try:
        link.open()
    except RigError:
        raise RigError(f"{lost} and reconnecting failed") from None


def short_error(exc: BaseException) -> str:
    """First line of an exception message (or its type name), for one-line errors."""
    return str(exc).splitlines()[0][:160] if str(exc) else type(exc).__name__


def reply_number(where: str, command: str, reply: str, field: int | None = None, separator: str = ",") -> float:
    """The number in ``reply`` (or in its ``field``-th ``separator``-separated part); RigError if malformed."""
    text = reply
    if field is not None:
        parts = reply.split(separator)
        if len(parts) <= field:
            raise RigError(f"{where}: malformed reply {reply!r} to {command!r} (expected at least {field + 1} "
                           f"{separator!r}-separated fields)")
        text = parts[field]
    try:
        value = float(text.strip())
    except ValueError:
        raise RigError(f"{where}: malformed reply {reply!r} to {command!r} (expected a number)") from None
    if value != value or value in (float("inf"), float("-inf")):
        raise RigError(f"{where}: malformed reply {reply!r} to {command!r} (not a finite number)")
    return value
