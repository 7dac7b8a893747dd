"""Hardware-in-the-loop simulator: the real drivers against loopback servers with the virtual lab behind them.

:class:`HilLab` serves, on 127.0.0.1, what a rig configuration (``driver: real``) expects:

- the turntable controller: a TCP line server answering the configured ``table_controller``
  command set (a PyVISA ``TCPIP0::127.0.0.1::PORT::SOCKET`` resource talks to it); position
  moves follow the rest-to-rest profile of the simulated rig at the position-mode rate and
  acceleration limits last commanded (``position_rate`` / ``position_accel``, or the
  ``{rate_dps}`` / ``{accel_dps2}`` fields of ``position``; default 60 °/s capped at
  ``turntable.max_rate_dps``, and ``turntable.max_accel_dps2``), and every setting command is
  logged with the simulated time it arrived (:attr:`HilLab.table_log`),
- the chamber controller: a TCP line server for the ASCII command set, or a pymodbus server
  with the configured register map,
- the IMU stream: frames in the configured format (TCP clients, or UDP datagrams to the
  configured address), produced by the :class:`~workbench.sim.rig.SimRig` of the unit (its
  motion, truth and virtual IMU) as the commanded table moves.

The simulated clock can run ``speed`` times faster than the wall clock (``hil.speed``); the
drivers time everything by the stream's sample counter, so a run is the same at any speed.
Faults for tests (:meth:`HilLab.inject`): ``silent`` (no replies), ``garbage`` (malformed
replies), ``refuse`` (setpoints refused), ``drop`` (the link is closed, and the next
connection too), ``interlock`` (the table reports an interlock); for the stream ``corrupt``,
``jump`` (the counter skips) and ``drop``.

The servers themselves (line server, Modbus server, ports) are :mod:`workbench.sim.hil_servers`;
this module is the lab behind them (motion engine, command sets, stream frames).
"""

from __future__ import annotations

import logging
import socket
import struct
import threading
import time
from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from workbench.angles import wrap_2pi, wrap_pi
from workbench.drivers.imu_stream import SIGNALS, FrameFormat
from workbench.drivers.turntable_visa import DEFAULT_COMMANDS, DEFAULT_POSITIONING_RATE
from workbench.errors import RigError
from workbench.rigconfig import RigConfig
from workbench.sim.hil_servers import (HOST, LineServer, ModbusChamberServer, free_port,  # noqa: F401 (re-exported)
                                       port_of, template_regex)
from workbench.sim.rig import SimRig, move_profile, ramp_profile

log = logging.getLogger("workbench.hil")
_TICK_S = 0.01  # wall-clock period of the motion engine
MAX_SPEED = 1000.0  # simulated s per wall-clock s: a cap above what the engine serves (1e5 samples/s at 100 Hz)


class HilLab:
    """The loopback rig for a configuration (see the module docstring); use :meth:`start` / :meth:`stop`.

    Parameters
    ----------
    cfg : rig configuration with ``driver: real`` and the ``hil`` section (``unit``, ``seed``,
        ``speed``) or the ``truth`` given here
    truth : the simulated unit (UnitTruth); default drawn from ``hil.unit`` with ``hil.seed``
    speed : simulated seconds per wall-clock second (default ``hil.speed`` or 1)
    free_ports : serve on free ports instead of the configured ones (tests); :attr:`config` then
        points at them
    """

    def __init__(self, cfg: RigConfig, truth=None, seed: int | None = None, speed: float | None = None,
                 free_ports: bool = False) -> None:
        from workbench.grades import draw_unit, load_spec

        opts = cfg.options
        hil = opts.get("hil") or {}
        self.seed = int(seed if seed is not None else hil.get("seed", 1))
        self.speed = float(speed if speed is not None else hil.get("speed", 1.0))
        if not 0 < self.speed <= MAX_SPEED:  # NaN and inf fail too: the motion engine's tick count
            raise RigError(f"rig {cfg.name}: hil speed {self.speed:g}: expected simulated seconds per wall-clock "
                           f"second in (0, {MAX_SPEED:g}]")
        missing = [k for k in ("table_controller", "imu_stream") if k not in opts]
        if missing:
            raise RigError(f"rig {cfg.name}: not a hardware-in-the-loop configuration (no {', '.join(missing)}; "
                           "e.g. fixtures/rigs/hil.yaml)")
        self.stream_settings = dict(opts["imu_stream"])
        self.fs = float(self.stream_settings["sample_rate_hz"])
        if truth is None:
            truth = draw_unit(load_spec(hil.get("unit", "industrial_mems")), self.seed)
        self.truth = replace(truth, sample_rate_hz=self.fs)
        self.format = FrameFormat.from_settings(self.stream_settings, "hil imu stream")
        self.modulo = int(self.stream_settings.get("counter_modulo", 2 ** 32))
        self.sim = SimRig(cfg, self.truth, self.seed)
        self.lock = threading.RLock()
        self.faults: dict[str, str | None] = {"table": None, "chamber": None, "stream": None}
        self._queue = np.zeros(0)  # pending table-rate profile, rad/s per sample
        self._hold = 0.0  # rate after the profile
        self._pos_rate = min(cfg.turntable.max_rate, DEFAULT_POSITIONING_RATE)  # position-mode limits, rad/s
        self._pos_accel = cfg.turntable.max_accel  # rad/s^2
        self.table_log: list[tuple[float, str, dict]] = []  # (simulated time s, command key, fields as sent)
        self._new_error = True
        self._errors: list[str] = []
        self._counter_skip = 0
        self._stop = threading.Event()
        self._servers: list = []
        self._stream_clients: set[socket.socket] = set()
        self._stream_server: socket.socket | None = None
        self._engine: threading.Thread | None = None
        self.cfg = cfg
        self.config = self._addresses(cfg, free_ports)

    # -- configuration ----------------------------------------------------------------------
    def _addresses(self, cfg: RigConfig, free_ports: bool) -> RigConfig:
        """The configuration with each device's address on 127.0.0.1 (free ports if asked)."""
        opts = {k: dict(v) if isinstance(v, Mapping) else v for k, v in cfg.options.items()}
        tc, ch, st = opts["table_controller"], opts.get("chamber_controller"), opts["imu_stream"]
        self.table_port = free_port() if free_ports else port_of(tc["resource"], "table_controller.resource")
        tc["resource"] = f"TCPIP0::{HOST}::{self.table_port}::SOCKET"
        if ch:
            if ch.get("driver") == "modbus":
                self.chamber_port = free_port() if free_ports else int(ch.get("port", 502))
                ch.update(host=HOST, port=self.chamber_port)
            else:
                self.chamber_port = free_port() if free_ports else port_of(ch["address"], "chamber_controller.address")
                ch["address"] = f"socket://{HOST}:{self.chamber_port}"
        addr = st["address"]
        scheme = "udp" if addr.startswith("udp://") else "socket"
        self.stream_port = free_port() if free_ports else port_of(addr, "imu_stream.address")
        st["address"] = f"{scheme}://{HOST}:{self.stream_port}"
        return replace(cfg, options=opts)

    # -- lifecycle ------------------------------------------------------------------------
    def start(self) -> HilLab:
        """Start the servers and the motion engine; returns self (everything stopped again on failure)."""
        try:
            self._start()
        except BaseException:
            self.stop()
            raise
        return self

    def _start(self) -> None:
        opts = self.config.options
        tc = opts["table_controller"]
        table = LineServer("table", self.table_port, self._table_reply, self.faults,
                           tc.get("write_termination", "\n"), tc.get("read_termination", "\n"))
        self._servers.append(table)
        self._table_patterns = [(k, template_regex(v)) for k, v in {**DEFAULT_COMMANDS, **(tc.get("commands") or {})}
                                .items() if v]
        ch = opts.get("chamber_controller")
        if ch and ch.get("driver") == "modbus":
            self._servers.append(ModbusChamberServer(self, ch))
        elif ch:
            from workbench.drivers.chamber_ascii import DEFAULTS

            self._chamber = {**DEFAULTS, **ch}
            self._chamber_set = template_regex(self._chamber["set"])
            self._servers.append(LineServer("chamber", self.chamber_port, self._chamber_reply, self.faults,
                                            ch.get("write_termination", "\r\n"), ch.get("read_termination", "\r\n")))
        for s in self._servers:
            s.start()
        if not self.config.options["imu_stream"]["address"].startswith("udp://"):
            try:
                self._stream_server = socket.create_server((HOST, self.stream_port))
            except OSError as exc:
                raise RigError(f"hil: imu stream port {self.stream_port}: {exc}") from None
            self._stream_server.settimeout(0.05)
        self._engine = threading.Thread(target=self._run, name="hil-engine", daemon=True)
        self._engine.start()

    def stop(self) -> None:
        """Stop the engine and every server, closing all connections (idempotent)."""
        if self._stop.is_set():
            return
        self._stop.set()
        if self._engine is not None:
            self._engine.join(timeout=2.0)
        for s in self._servers:
            s.stop()
        for c in list(self._stream_clients):
            c.close()
        self._stream_clients.clear()
        if self._stream_server is not None:
            self._stream_server.close()

    def __enter__(self) -> HilLab:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def inject(self, device: str, fault: str | None) -> None:
        """Inject a fault into ``device`` (table | chamber | stream); None clears it."""
        if device not in self.faults:
            raise RigError(f"hil: unknown device {device!r} (known: {', '.join(self.faults)})")
        self.faults[device] = fault
        if device == "stream" and fault == "jump":
            self._counter_skip = 50

    # -- motion engine --------------------------------------------------------------------
    def _rates(self, n: int) -> np.ndarray:
        take = self._queue[:n]
        self._queue = self._queue[n:]
        return np.concatenate([take, np.full(n - len(take), self._hold)])

    def _plan(self, target_angle: float | None, target_rate: float, turn: float | None = None) -> None:
        """Replace the pending motion: decelerate / accelerate, or a rest-to-rest move to an angle
        (the shortest way) or by ``turn`` rad (signed)."""
        tt, st = self.cfg.turntable, self.sim.state
        r0 = st.table_rate
        if target_angle is None and turn is None:
            self._queue = ramp_profile(r0, target_rate, tt.max_accel, self.fs) if r0 != target_rate else np.zeros(0)
            self._hold = target_rate
            return
        decel = ramp_profile(r0, 0.0, tt.max_accel, self.fs) if r0 != 0.0 else np.zeros(0)
        prev = np.concatenate([[r0], decel[:-1]])
        after = st.table_angle + float(np.sum(0.5 * (prev + decel)) / self.fs)
        delta = turn if turn is not None else wrap_pi(target_angle - after)
        move = move_profile(delta, self._pos_rate, self._pos_accel, self.fs) if abs(delta) > 1e-12 else np.zeros(0)
        self._queue, self._hold = np.concatenate([decel, move]), 0.0
        self._new_error = True

    def _run(self) -> None:
        try:
            self._loop()
        except Exception:  # the stream stops; the drivers report it, the log says why
            log.exception("hil: motion engine stopped")

    def _loop(self) -> None:
        tick = max(_TICK_S, 100.0 / (self.fs * self.speed))  # >= 100 samples per tick when fast
        per_tick = self.fs * self.speed * tick
        owed, next_tick = 0.0, time.monotonic()
        while not self._stop.is_set():
            self._accept_stream_clients()
            owed += per_tick
            n = int(owed)
            owed -= n
            if n:
                with self.lock:
                    df = self.sim.advance(self._rates(n), new_fixture_error=self._new_error)
                    self._new_error = False
                self._send_frames(df)
            next_tick += tick
            time.sleep(max(0.0, next_tick - time.monotonic()))

    def _accept_stream_clients(self) -> None:
        if self._stream_server is None:
            return
        try:
            conn, _ = self._stream_server.accept()
        except (TimeoutError, OSError):
            return
        conn.settimeout(1.0)  # a client that stops reading is dropped instead of stalling the engine
        self._stream_clients.add(conn)

    def _send_frames(self, df) -> None:
        fault = self.faults["stream"]
        if fault == "silent":
            return
        if fault == "drop":
            self.faults["stream"] = None
            for c in list(self._stream_clients):
                c.close()
            self._stream_clients.clear()
            return
        values = {c: df[c].to_numpy() for c in SIGNALS if c in df.columns}
        samples = np.round(df["t"].to_numpy() * self.fs).astype(np.int64)
        if self._counter_skip:
            samples = samples + self._counter_skip
            self.faults["stream"] = None
        values.update(counter=samples % self.modulo, time=samples / self.fs)
        data = self.format.encode(values)
        if fault == "corrupt":  # every frame unreadable: garbage lines, or payload bytes 0xFF (NaN, bad checksum)
            if self.format.kind == "text":
                data = b"#garbage\n" * len(samples)
            else:
                frames = np.frombuffer(data, np.uint8).reshape(len(samples), -1).copy()
                frames[:, len(self.format.sync):len(self.format.sync) + struct.calcsize(self.format.layout)] = 0xFF
                data = frames.tobytes()
        address = self.config.options["imu_stream"]["address"]
        if address.startswith("udp://"):
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
                for datagram in self._datagrams(data, len(samples)):
                    s.sendto(datagram, (HOST, self.stream_port))
            return
        for c in list(self._stream_clients):
            try:
                c.sendall(data)
            except OSError:
                self._stream_clients.discard(c)
                c.close()

    @staticmethod
    def _datagrams(data: bytes, frames: int, size: int = 8192) -> list[bytes]:
        """``data`` (``frames`` equal-length frames or text lines) cut into datagrams of whole frames."""
        pieces = data.splitlines(keepends=True) if data.endswith(b"\n") else \
            [data[i:i + len(data) // frames] for i in range(0, len(data), len(data) // frames)]
        out, cur = [], b""
        for p in pieces:
            if cur and len(cur) + len(p) > size:
                out.append(cur)
                cur = b""
            cur += p
        return out + [cur] if cur else out

    # -- table controller -----------------------------------------------------------------
    def _table_reply(self, line: str) -> str | None:
        for key, pattern in self._table_patterns:
            m = pattern.match(line)
            if m:
                with self.lock:
                    return self._table_command(key, {k: v for k, v in m.groupdict().items()})
        self._errors.append("-113,Undefined header")
        return "ERR -113,Undefined header" if line.endswith("?") else None

    def _table_command(self, key: str, f: dict) -> str | None:
        st, tt = self.sim.state, self.cfg.turntable
        refuse = self.faults["table"] == "refuse"
        if key == "identify":
            return "HIL,workbench turntable simulator,0,1.0"
        if key == "read_angle":
            res = tt.encoder_resolution
            return f"{np.degrees(wrap_2pi(np.round(st.table_angle / res) * res)):.6f}"
        if key == "read_rate":
            return f"{np.degrees(st.table_rate):.6f}"
        if key == "status":
            return "INTERLOCK DOOR OPEN" if self.faults["table"] == "interlock" else \
                f"READY,{'RATE' if self._hold else 'POSITION'}"
        if key == "interlock":
            return "1" if self.faults["table"] == "interlock" else "0"
        if key == "error":
            return self._errors.pop(0) if self._errors else "0,No error"
        self.table_log.append((st.sample / self.fs, key, dict(f)))
        if key == "stop":
            self._plan(None, 0.0)
        elif key in ("position", "position_rate", "position_accel", "position_relative"):
            rate = np.radians(float(f["rate_dps"])) if "rate_dps" in f else self._pos_rate
            accel = np.radians(float(f["accel_dps2"])) if "accel_dps2" in f else self._pos_accel
            if refuse or not (0 < rate <= tt.max_rate * (1 + 1e-6) and 0 < accel <= tt.max_accel * (1 + 1e-6)):
                self._errors.append("-222,Data out of range")
                return None
            self._pos_rate, self._pos_accel = rate, accel
            if key == "position":
                self._plan(np.radians(float(f["angle_deg"])), 0.0)
            elif key == "position_relative":
                self._plan(None, 0.0, turn=np.radians(float(f["delta_deg"])))
        elif key == "rate":
            rate = np.radians(float(f["rate_dps"]))
            if refuse or abs(rate) > tt.max_rate * (1 + 1e-6):
                self._errors.append("-222,Data out of range")
            else:
                self._plan(None, rate)
        elif key == "mount":
            m = np.array([float(x) for x in f["mount"].split(",")]).reshape(3, 3)
            st.mount = m.tolist()
            self._new_error = True
        return None

    # -- ASCII chamber ----------------------------------------------------------------------
    def _set_chamber(self, setpoint_c: float) -> bool:
        ch = self.cfg.chamber
        if self.faults["chamber"] == "refuse" or not ch.min_c <= setpoint_c <= ch.max_c:
            return False
        with self.lock:
            self.sim.state.chamber_target_c = float(setpoint_c)
            self.sim.state.chamber_rate_c_per_min = ch.max_ramp_c_per_min
        return True

    def _chamber_reply(self, line: str) -> str | None:
        c, st = self._chamber, self.sim.state
        if line == c["identify"]:
            return "HIL ESPEC-STYLE CHAMBER SIMULATOR"
        if line == c["read"]:
            return f"{st.air_c:.2f},{st.chamber_target_c:.1f},{self.cfg.chamber.max_c:.1f},{self.cfg.chamber.min_c:.1f}"
        m = self._chamber_set.match(line)
        if m:
            value = float(m.group("setpoint_c"))
            return f"OK: {line}" if self._set_chamber(value) else "NA:DATA OUT OF RANGE"
        return "NA:COMMAND ERROR"
