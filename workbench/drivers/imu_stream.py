"""IMU sample stream reader: serial (pyserial), TCP or UDP; text or binary frames; SI out.

``imu_stream`` of the rig configuration::

    address: /dev/ttyUSB0 | socket://127.0.0.1:5600 (tcp://) | udp://127.0.0.1:5600  (udp: the local port to listen on)
    baudrate: 921600
    sample_rate_hz: 100
    format: text                  # or binary
    fields: [counter, gx, gy, gz, ax, ay, az, temp]   # 'counter', 'time' (device s), 'gx'.. 'mz', 'temp', '_' (skip)
    separator: ","                # text
    checksum: none                # or xor8: text "...*HH" (NMEA-style), binary one byte after the payload
    sync: "a55a"                  # binary: hex bytes that start a frame
    struct: "<I7f"                # binary: payload layout (Python struct), one item per field
    scale: {gx: 0.0174532925, ax: 9.80665}   # raw * scale = SI (rad/s, m/s^2, µT, °C); default 1
    counter_modulo: 4294967296    # the counter wraps at this value
    time_source: counter          # counter | time | host: what sets the sample times
    max_corrupt_frames: 3         # per step; one more stops the run naming the frame
    timeout_s: 1.0                # no frame for this long = the stream stopped

Every frame gets a host timestamp (``time.monotonic``) on arrival. Sample times come from the
counter or device time (``t = index / fs``, continuing across steps and resumed runs); one
missing frame is counted as dropped (the session format tolerates one missing sample), a larger
jump or a step backwards is a :class:`RigError` naming the frame.
"""

from __future__ import annotations

import functools
import math
import queue
import socket
import struct
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import serial

from workbench.drivers.transport import short_error
from workbench.errors import RigError

SIGNALS = ("gx", "gy", "gz", "ax", "ay", "az", "mx", "my", "mz", "temp")
_KNOWN_FIELDS = {*SIGNALS, "counter", "time", "_"}
_TIME_SOURCES = ("counter", "time", "host")
_READ = 65536  # bytes per read of the link


def xor8(data: bytes) -> int:
    """XOR of all bytes (NMEA-style checksum)."""
    c = 0
    for b in data:
        c ^= b
    return c


@dataclass(frozen=True)
class FrameFormat:
    """How one frame is laid out on the wire and scaled to SI (see the module docstring)."""

    kind: str
    fields: tuple[str, ...]
    separator: str = ","
    checksum: str = "none"
    sync: bytes = b""
    layout: str = ""
    scale: Mapping[str, float] = field(default_factory=dict)

    @classmethod
    def from_settings(cls, s: Mapping, where: str) -> FrameFormat:
        """Parse and check the ``imu_stream`` settings; RigError naming the field at fault."""
        kind = s.get("format", "text")
        if kind not in ("text", "binary"):
            raise RigError(f"{where}: format {kind!r} (expected text or binary)")
        fields_ = tuple(s.get("fields") or ())
        bad = [f for f in fields_ if f not in _KNOWN_FIELDS]
        if not fields_ or bad:
            raise RigError(f"{where}: fields {list(fields_)} (unknown {bad}; "
                           f"known: {', '.join(sorted(_KNOWN_FIELDS))})")
        missing = [c for c in ("gx", "gy", "gz", "ax", "ay", "az") if c not in fields_]
        if missing:
            raise RigError(f"{where}: fields lack {', '.join(missing)}")
        checksum = s.get("checksum", "none")
        if checksum not in ("none", "xor8"):
            raise RigError(f"{where}: checksum {checksum!r} (expected none or xor8)")
        layout, sync = str(s.get("struct", "")), bytes.fromhex(str(s.get("sync", "")))
        if kind == "binary":
            try:
                n = len(struct.unpack(layout, bytes(struct.calcsize(layout))))
            except struct.error as exc:
                raise RigError(f"{where}: struct {layout!r}: {exc}") from None
            if n != len(fields_):
                raise RigError(f"{where}: struct {layout!r} holds {n} items for {len(fields_)} fields")
            if not sync:
                raise RigError(f"{where}: a binary format needs 'sync' bytes (hex)")
        scale = {k: float(v) for k, v in (s.get("scale") or {}).items()}
        return cls(kind, fields_, str(s.get("separator", ",")), checksum, sync, layout, scale)

    @property
    def frame_size(self) -> int:
        """Bytes per binary frame (sync + payload + checksum)."""
        return len(self.sync) + struct.calcsize(self.layout) + (1 if self.checksum == "xor8" else 0)

    def parse(self, raw: bytes) -> list[float]:
        """Values of one frame (sync/terminator removed) in ``fields`` order, scaled to SI; ValueError if bad."""
        if self.kind == "text":
            text = raw.decode("ascii").strip()
            if self.checksum == "xor8":
                body, star, check = text.rpartition("*")
                if not star or int(check, 16) != xor8(body.encode("ascii")):
                    raise ValueError("checksum mismatch")
                text = body
            parts = text.split(self.separator)
            if len(parts) != len(self.fields):
                raise ValueError(f"{len(parts)} fields, expected {len(self.fields)}")
            values = [float(p) for p in parts]
        else:
            payload = raw[:len(raw) - (self.checksum == "xor8")]
            if self.checksum == "xor8" and raw[-1] != xor8(payload):
                raise ValueError("checksum mismatch")
            values = struct.unpack(self.layout, payload)
        if not all(map(math.isfinite, values)):
            raise ValueError("non-finite value")
        return [v * k for v, k in zip(values, self._factors)]

    @functools.cached_property
    def _factors(self) -> list[float]:
        return [self.scale.get(f, 1.0) for f in self.fields]

    def encode(self, values: Mapping[str, np.ndarray]) -> bytes:
        """Frames on the wire from SI columns ``values`` (field -> (N,) array); the HIL simulator's side.

        The inverse of :meth:`parse`; fields missing from ``values`` are sent as 0.
        """
        n = len(next(iter(values.values())))
        raw = [np.asarray(values.get(f, np.zeros(n)), float) / self.scale.get(f, 1.0) for f in self.fields]
        if self.kind == "text":
            fmt = self.separator.join("%d" if f == "counter" else "%.10g" for f in self.fields)
            lines = [fmt % row for row in zip(*raw)]
            if self.checksum == "xor8":
                lines = [f"{line}*{xor8(line.encode('ascii')):02X}" for line in lines]
            return ("\n".join(lines) + "\n").encode("ascii")
        order = "<" if self.layout[:1] in "<=" else ">" if self.layout[:1] in ">!" else "="
        codes = _expand_codes(self.layout.lstrip("<>=!@"))
        dtype = np.dtype([(f"f{i}", order + c) for i, c in enumerate(codes)])
        rec = np.empty(n, dtype)
        for i, (c, v) in enumerate(zip(codes, raw)):
            rec[f"f{i}"] = v if c in "efd" else np.round(v)
        payload = rec.view(np.uint8).reshape(n, dtype.itemsize)
        parts = [np.broadcast_to(np.frombuffer(self.sync, np.uint8), (n, len(self.sync))), payload]
        if self.checksum == "xor8":
            parts.append(np.bitwise_xor.reduce(payload, axis=1)[:, None])
        return np.hstack(parts).tobytes()


def _expand_codes(codes: str) -> list[str]:
    out, num = [], ""
    for ch in codes:
        if ch.isdigit():
            num += ch
        else:
            out.extend([ch] * int(num or 1))
            num = ""
    return out


@dataclass
class Block:
    """Frames taken from the stream: sample times (s), host arrival times (s), SI columns."""

    t: np.ndarray
    host_t: np.ndarray
    columns: dict[str, np.ndarray]


class ImuStream:
    """Reads frames in a background thread; :meth:`take` hands them out as SI blocks."""

    def __init__(self, settings: Mapping, name: str = "imu stream", start_sample: int = 0) -> None:
        for key in ("address", "sample_rate_hz"):
            if key not in settings:
                raise RigError(f"{name}: missing field 'imu_stream.{key}'")
        self.address = str(settings["address"])
        self.where = f"{name} ({self.address})"
        self.fs = float(settings["sample_rate_hz"])
        self.format = FrameFormat.from_settings(settings, self.where)
        self.baudrate = int(settings.get("baudrate", 115200))
        self.timeout_s = float(settings.get("timeout_s", 1.0))
        self.max_corrupt = int(settings.get("max_corrupt_frames", 3))
        self.modulo = int(settings.get("counter_modulo", 2 ** 32))
        self.time_source = settings.get("time_source", "counter" if "counter" in self.format.fields else "host")
        if self.time_source not in _TIME_SOURCES or (self.time_source != "host"
                                                     and self.time_source not in self.format.fields):
            raise RigError(f"{self.where}: time_source {self.time_source!r} needs a field of that name "
                           f"(or 'host'); fields {list(self.format.fields)}")
        self.next_sample = int(start_sample)  # session sample index of the next frame
        self.frames = 0  # frames handed out
        self.dropped = 0
        self.corrupt = 0
        self._last_stamp: float | None = None
        self._queue: queue.Queue = queue.Queue()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # -- link -------------------------------------------------------------------------
    def open(self) -> None:
        """Connect and start reading; RigError if the address does not answer."""
        try:
            scheme, _, rest = self.address.partition("://")
            if scheme in ("udp", "socket", "tcp"):
                host, port = rest.rsplit(":", 1)
                if scheme == "udp":
                    link = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                    link.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)  # ride out reader stalls
                    link.bind((host, int(port)))
                else:
                    link = socket.create_connection((host, int(port)), timeout=self.timeout_s)
                link.settimeout(0.1)
            else:
                link = serial.serial_for_url(self.address, baudrate=self.baudrate, timeout=0.05)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise RigError(f"{self.where}: cannot connect ({short_error(exc)})") from None
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, args=(link,), name="imu-stream", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop reading and release the link (idempotent)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None

    def _run(self, link) -> None:
        buf = b""
        is_socket = isinstance(link, socket.socket)
        tcp = is_socket and link.type == socket.SOCK_STREAM
        try:
            while not self._stop.is_set():
                started = time.monotonic()
                try:
                    data = link.recv(_READ) if is_socket else link.read(_READ)
                except TimeoutError:
                    data = None
                if not data:
                    if tcp and data is not None:
                        raise ConnectionError("closed by the sender")
                    self._queue.put(("mark", started, False))
                    continue
                now = time.monotonic()
                if is_socket and not tcp:  # a datagram holds whole frames (the last may lack its terminator)
                    rest = self._split(data, now)
                    if rest.strip() and self.format.kind == "text":
                        self._put(rest, now)
                    elif rest:
                        self._queue.put(("bad", now, rest, "incomplete frame at the end of a datagram"))
                else:
                    buf = self._split(buf + data, now)
                # everything that had arrived when this read started has now been queued (unless it filled up)
                self._queue.put(("mark", started, len(data) == _READ))
        except (serial.SerialException, OSError) as exc:
            self._queue.put(("lost", time.monotonic(), short_error(exc)))
        finally:
            link.close()

    def _split(self, buf: bytes, now: float) -> bytes:
        fmt = self.format
        if fmt.kind == "text":
            *lines, rest = buf.split(b"\n")
            for line in lines:
                if line.strip():
                    self._put(line, now)
            return rest
        size = fmt.frame_size
        while True:
            k = buf.find(fmt.sync)
            if k < 0:
                return buf[-(len(fmt.sync) - 1):] if len(fmt.sync) > 1 else b""
            if k > 0:
                self._queue.put(("bad", now, buf[:k], "bytes before the sync word"))
            if len(buf) - k < size:
                return buf[k:]
            self._put(buf[k + len(fmt.sync):k + size], now)
            buf = buf[k + size:]

    def _put(self, raw: bytes, now: float) -> None:
        try:
            self._queue.put(("ok", now, self.format.parse(raw)))
        except (ValueError, UnicodeDecodeError, struct.error) as exc:
            self._queue.put(("bad", now, raw, str(exc)))

    # -- frames -----------------------------------------------------------------------
    def reset_counts(self) -> dict:
        """Frame statistics since the last reset (``frames``, ``dropped``, ``corrupt``), then zero them."""
        counts = {"frames": self.frames, "dropped_frames": self.dropped, "corrupt_frames": self.corrupt}
        self.frames = self.dropped = self.corrupt = 0
        return counts

    def _next_item(self):
        try:
            return self._queue.get(timeout=self.timeout_s)
        except queue.Empty:
            raise RigError(f"{self.where}: no frame for {self.timeout_s:g} s (after sample "
                           f"{self.next_sample - 1})") from None

    def _accept(self, values: np.ndarray, host_t: float) -> int:
        """Session sample index of a good frame; checks the counter / device time."""
        fields_ = self.format.fields
        if self.time_source == "host":
            stamp, step = host_t, 1
        else:
            stamp = float(values[fields_.index(self.time_source)])
            if self._last_stamp is None:
                step = 1
            elif self.time_source == "counter":
                step = int(round(stamp - self._last_stamp)) % self.modulo
            else:
                step = int(round((stamp - self._last_stamp) * self.fs))
        if self._last_stamp is not None and self.time_source != "host" and not 1 <= step <= 2:
            raise RigError(f"{self.where}: timestamps jump at frame {self.frames + 1} after sample "
                           f"{self.next_sample - 1}: {self.time_source} {self._last_stamp:g} -> {stamp:g} "
                           f"({step} sample intervals)")
        self._last_stamp = stamp
        self.dropped += step - 1
        index = self.next_sample + step - 1
        self.next_sample = index + 1
        return index

    def take(self, n: int | None = None, until_host_t: float | None = None) -> Block:
        """The next ``n`` frames, or every frame that had reached the host by ``until_host_t`` (monotonic s).

        With ``until_host_t`` it waits until the reader has read the link once after that
        instant, so frames still in the operating system's buffers are included however far
        the reader lags. RigError when the stream stops, a frame does not parse beyond
        ``max_corrupt_frames``, the timestamps jump, or the link is lost.
        """
        idx, host, rows = [], [], []
        deadline = time.monotonic() + self.timeout_s
        while until_host_t is not None or len(rows) < n:
            item = self._next_item()
            if item[0] == "mark":
                if until_host_t is not None and item[1] >= until_host_t and not item[2]:
                    break
                if time.monotonic() > deadline:
                    raise RigError(f"{self.where}: no frame for {self.timeout_s:g} s (after sample "
                                   f"{self.next_sample - 1})")
                continue
            if item[0] == "lost":
                raise RigError(f"{self.where}: connection lost after sample {self.next_sample - 1} ({item[2]})")
            if item[0] == "bad":
                self.corrupt += 1
                if self.corrupt > self.max_corrupt:
                    raise RigError(f"{self.where}: frame after sample {self.next_sample - 1} does not parse "
                                   f"({item[3]}): {item[2][:60]!r} ({self.corrupt} bad frames in this step, "
                                   f"max_corrupt_frames {self.max_corrupt})")
                continue
            idx.append(self._accept(item[2], item[1]))
            host.append(item[1])
            rows.append(item[2])
            self.frames += 1
            deadline = time.monotonic() + self.timeout_s
        data = np.array(rows).reshape(len(rows), len(self.format.fields))
        cols = {f: data[:, i] for i, f in enumerate(self.format.fields) if f in SIGNALS}
        return Block(np.asarray(idx, float) / self.fs, np.asarray(host, float), cols)
