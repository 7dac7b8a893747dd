"""A real rig: turntable + climatic chamber + IMU stream behind the simulated rig's interface.

:func:`open_real_rig` builds a :class:`RealRig` from a rig configuration with ``driver: real``
(sections ``table_controller``, ``chamber_controller``, ``imu_stream``, ``fixture``; see
``docs/rigs.md``). For each planned step the rig

1. sets the chamber (soak / ramp setpoints; ramps are stepped from the host),
2. remounts the unit (``fixture.mode``: ``command`` = a motorised fixture or the HIL simulator,
   ``prompt`` = asks the operator, ``fixed`` = refuses plans that need a remount),
3. moves the table (position mode, or rate mode for rate / carousel steps) and waits until the
   read-back angle and rate are within tolerance, then ``turntable.settle_s`` more; position
   moves carry their rate limit (an index step's ``index_rate``, else
   ``table_controller.positioning_rate_dps``) and ``turntable.max_accel_dps2`` where the command
   set can send them (``position_rate`` / ``position_accel``, see ``turntable_visa``),
4. records the stream: transition samples labelled ``step = -1``, then the step's samples,
   each with the table's read-back angle and rate (read once per ``poll_s`` of samples and
   extrapolated to each sample with the read-back rate).

Between chunks it polls the controller's interlock: an interlock stops the run with the step
named. :meth:`RealRig.safe` stops the table and sends the chamber to its safe setpoint and logs
what it did (``workbench.rig`` logger, WARNING). Sample times come from the stream's counter,
so a resumed run continues the time axis of the interrupted one.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import numpy as np
import pandas as pd

from workbench.drivers.imu_stream import Block, ImuStream
from workbench.drivers.turntable_visa import DEFAULT_POSITIONING_RATE, VisaTurntable
from workbench.angles import wrap_2pi, wrap_pi
from workbench.errors import RigError, RigLimitError, WorkbenchError
from workbench.motion import RigState
from workbench.rigconfig import RigConfig, check_plan
from workbench.sequence import PlannedStep, mount_label
from workbench.session import StepRecord

log = logging.getLogger("workbench.rig")
DRIVERS = ("sim", "real")
CHAMBER_DRIVERS = ("ascii", "modbus")
FIXTURE_MODES = ("prompt", "command", "fixed")


def open_chamber(settings, name: str):
    """The chamber driver named by ``chamber_controller.driver`` (ascii | modbus)."""
    kind = settings.get("driver")
    if kind == "ascii":
        from workbench.drivers.chamber_ascii import AsciiChamber

        return AsciiChamber(settings, name)
    if kind == "modbus":
        from workbench.drivers.chamber_modbus import ModbusChamber

        return ModbusChamber(settings, name)
    raise RigError(f"{name}: unknown chamber_controller.driver {kind!r} (known: {', '.join(CHAMBER_DRIVERS)})")


def open_real_rig(cfg: RigConfig, truth=None, seed: int = 0, state: RigState | None = None,
                  prompt: Callable[[str], object] = input) -> RealRig:
    """Connect to the rig of ``cfg`` (``driver: real``); ``truth``/``seed`` are unused on hardware.

    ``state``: the saved state of an interrupted recording (``--resume``). RigError naming
    the device if a field is missing or an address does not answer.
    """
    if cfg.driver != "real":
        raise RigError(f"rig {cfg.name}: unknown driver {cfg.driver!r} (known: {', '.join(DRIVERS)})")
    opts = cfg.options
    for key in ("table_controller", "imu_stream"):
        if not isinstance(opts.get(key), dict):
            raise RigError(f"rig {cfg.name}: missing field {key!r}")
    fixture = opts.get("fixture") or {"mode": "prompt"}
    if fixture.get("mode") not in FIXTURE_MODES:
        raise RigError(f"rig {cfg.name}: fixture.mode {fixture.get('mode')!r} (known: {', '.join(FIXTURE_MODES)})")
    table = VisaTurntable(opts["table_controller"], f"rig {cfg.name}: turntable")
    chamber = open_chamber(opts["chamber_controller"], f"rig {cfg.name}: chamber") \
        if opts.get("chamber_controller") else None
    stream = ImuStream(opts["imu_stream"], f"rig {cfg.name}: imu stream", state.sample if state else 0)
    devices = [d for d in (table, chamber, stream) if d is not None]
    try:
        for d in devices:
            d.open()
        table.identify()  # an address that accepts a connection but does not answer fails here
        return RealRig(cfg, table, chamber, stream, fixture, state, prompt)
    except BaseException:
        for d in devices:
            d.close()
        raise


class RealRig:
    """Turntable, chamber and IMU stream driven through one planned step at a time (see the module)."""

    driver = "real"

    def __init__(self, cfg: RigConfig, table: VisaTurntable, chamber, stream: ImuStream, fixture: dict,
                 state: RigState | None = None, prompt: Callable[[str], object] = input) -> None:
        self.config, self.name, self.site = cfg, cfg.name, cfg.site
        self.table, self.chamber, self.stream = table, chamber, stream
        self.fs = stream.fs
        self.fixture_mode = fixture.get("mode", "prompt")
        self.prompt = prompt
        tc = cfg.options["table_controller"]
        self.angle_tol = np.radians(float(tc.get("angle_tolerance_deg", 0.005)))
        self.rate_tol = np.radians(float(tc.get("rate_tolerance_dps", 0.01)))
        self.settle_timeout_s = float(tc.get("settle_timeout_s", 120.0))
        default_dps = np.degrees(min(cfg.turntable.max_rate, DEFAULT_POSITIONING_RATE))
        self.positioning_rate = np.radians(float(tc.get("positioning_rate_dps", default_dps)))
        self.chunk = max(1, int(round(float(tc.get("poll_s", 0.5)) * self.fs)))
        ch = cfg.options.get("chamber_controller") or {}
        self.air_tol_c = float(ch.get("air_tolerance_c", 0.5))
        c0 = cfg.chamber.initial_c
        self.state = state or RigState(air_c=c0, unit_c=c0, chamber_target_c=c0,
                                       chamber_rate_c_per_min=cfg.chamber.max_ramp_c_per_min, mount=None)
        self._mounted = False  # the first step always (re)mounts: after a resume the fixture is unknown
        self.safe_report: list[str] = []

    # -- interface shared with the simulated rig ------------------------------------------
    def check(self, plan: list[PlannedStep]) -> None:
        """RigLimitError if a step is outside the limits, needs a chamber that is not configured,
        or needs a remount on a ``fixed`` fixture, or a step's record would not fit in memory."""
        check_plan(plan, self.config, self.fs)
        self._check_position_moves(plan)
        for i, p in enumerate(plan):
            where = f"rig {self.name}: step {i} ({p.kind}{', ' + p.label if p.label else ''})"
            if self.chamber is None and p.temperature_c is not None:
                raise RigLimitError(f"{where}: needs a chamber setpoint but no chamber_controller is configured")
            if self.fixture_mode == "fixed" and not np.allclose(p.mount, plan[0].mount):
                raise RigLimitError(f"{where}: needs a remount to {mount_label(p.mount)} but fixture.mode is 'fixed'")

    def _check_position_moves(self, plan: list[PlannedStep]) -> None:
        """Positioning rate within the limit, position templates that format, and a WARNING when the
        index rates of the plan cannot be sent (the controller's own slew rate is used)."""
        source = self.config.path or f"rig {self.name}"
        max_rate, accel = self.config.turntable.max_rate, self.config.turntable.max_accel
        if not 0.0 < self.positioning_rate <= max_rate * (1 + 1e-9):
            raise RigLimitError(f"{source}: table_controller.positioning_rate_dps "
                                f"{np.degrees(self.positioning_rate):g} °/s outside 0..{np.degrees(max_rate):g} °/s "
                                f"(turntable.max_rate_dps)")
        rates = sorted({round(abs(p.table_rate), 12) for p in plan if p.kind == "index"})
        for rate in [self.positioning_rate, *rates]:
            self.table.position_commands(0.0, rate, accel)  # a template that does not format fails before moving
        if rates and self.table.turns_relative:
            self.table.position_commands(0.0, rates[0], accel, relative=True)
        if rates and not self.table.sends_position_rate:
            log.warning("%s: no 'position_rate' in table_controller.commands (nor {rate_dps} in 'position'): index "
                        "steps run at the controller's own slew rate, not at %s °/s", source,
                        ", ".join(f"{np.degrees(r):g}" for r in rates))

    def _position_limits(self) -> str:
        """What a position move carries (for ``rig check``): its rate and acceleration limits, or neither."""
        sent = [name for name, ok in (("rate", self.table.sends_position_rate),
                                      ("acceleration", self.table.sends_position_accel)) if ok]
        return f"{' and '.join(sent)} limit sent" if sent else \
            "controller's own slew rate (no 'position_rate' command: index rates not sent)"

    def identify(self) -> dict:
        """Identity, table position and rate, interlock, chamber temperature, a few stream frames.

        Moves nothing.
        """
        out = {"driver": self.driver, "name": self.name, "table": self.table.identify(),
               "table_angle_deg": float(np.degrees(self.table.angle())),
               "table_rate_dps": float(np.degrees(self.table.rate())),
               "interlock": self.table.interlock() or "clear",
               "position_moves": self._position_limits()}
        if self.chamber is not None:
            out.update(chamber=self.chamber.identify(), air_c=self.chamber.temperature())
        block = self.stream.take(max(2, int(self.fs // 2)))
        out.update(stream_frames=len(block.t), stream_span_s=float(block.t[-1] - block.t[0]),
                   stream_dropped=self.stream.dropped, stream_corrupt=self.stream.corrupt)
        if "temp" in block.columns:
            out["unit_c"] = float(np.mean(block.columns["temp"]))
        return out

    def safe(self) -> None:
        """Stop the table and send the chamber to its safe setpoint; log (WARNING) what was done."""
        report = []
        try:
            self.table.stop()
            report.append("table stopped")
        except WorkbenchError as exc:
            report.append(f"COULD NOT STOP THE TABLE, stop it by hand ({exc})")
        if self.chamber is not None:
            safe_c = self.config.chamber.safe_c
            try:
                self.chamber.set_setpoint(safe_c)
                report.append(f"chamber set to its safe setpoint {safe_c:g} °C")
            except WorkbenchError as exc:
                report.append(f"COULD NOT SET THE CHAMBER to {safe_c:g} °C ({exc})")
        self.state.table_rate = 0.0
        self.safe_report = report
        log.warning("rig %s: run stopped; %s", self.name, "; ".join(report))

    def close(self) -> None:
        """Release every link."""
        for d in (self.stream, self.table, self.chamber):
            if d is not None:
                d.close()

    def perform(self, planned: PlannedStep, index: int) -> tuple[pd.DataFrame, StepRecord]:
        """Run one planned step: transition (step -1) then the step; RigError names the step."""
        where = f"rig {self.name}: step {index} ({planned.kind}{', ' + planned.label if planned.label else ''})"
        try:
            return self._perform(planned, index)
        except RigError as exc:
            raise RigError(f"{where}: {exc}") from None

    # -- steps --------------------------------------------------------------------------
    def _perform(self, p: PlannedStep, index: int) -> tuple[pd.DataFrame, StepRecord]:
        self.stream.reset_counts()
        parts: list[pd.DataFrame] = []
        if self.chamber is not None and p.temperature_c is not None and p.temperature_c != self.state.chamber_target_c:
            self._setpoint(p.temperature_c)
        if not self._mounted or not np.allclose(p.mount, self.state.mount):
            parts.append(self._remount(p.mount))
        rotating = p.kind in ("rate", "carousel")
        if rotating:
            self.table.spin(p.table_rate)
            parts.append(self._wait_settled(None, p.table_rate, -1))
        else:
            self.table.goto(p.table_angle, self.positioning_rate, self.config.turntable.max_accel)
            parts.append(self._wait_settled(p.table_angle, 0.0, -1))
        parts.append(self._record(int(round(self.config.turntable.settle_s * self.fs)), -1))
        start_angle = self.table.angle()
        t_start = self.stream.next_sample / self.fs
        extra = dict(p.extra)
        if p.kind == "index":
            target = p.table_angle + p.extra["index_angle"]
            if self.table.turns_relative:  # the sequence's direction, not the controller's shortest way
                self.table.turn_by(p.extra["index_angle"], abs(p.table_rate), self.config.turntable.max_accel)
            else:
                self.table.goto(target, abs(p.table_rate), self.config.turntable.max_accel)
            parts.append(self._wait_settled(target, 0.0, index))
            extra["index_rate_sent"] = self.table.sends_position_rate  # False: the controller's own slew rate
        elif p.kind == "soak":
            parts.append(self._soak(p, index))
        elif p.kind == "ramp":
            parts.append(self._ramp(p, index))
        else:
            parts.append(self._record(max(1, int(round(p.duration_s * self.fs))), index))
        samples = _concat(parts)
        t_end = self.stream.next_sample / self.fs
        self.state.sample = self.stream.next_sample
        counts = self.stream.reset_counts()
        record = StepRecord(index, p.kind, t_start, t_end - 0.5 / self.fs, np.asarray(p.mount), float(start_angle),
                            float(p.table_rate), p.temperature_c, p.label,
                            {**extra, "dropped_frames": counts["dropped_frames"],
                             "corrupt_frames": counts["corrupt_frames"]})
        return samples, record

    def _setpoint(self, setpoint_c: float) -> None:
        self.chamber.set_setpoint(setpoint_c)
        self.state.chamber_target_c = float(setpoint_c)

    def _remount(self, mount: np.ndarray) -> pd.DataFrame:
        """Stop the table and put the unit on ``mount`` (command or operator); transition samples."""
        parts = []
        if self.state.table_rate != 0.0 or abs(self.table.rate()) > self.rate_tol:
            self.table.stop()
            parts.append(self._wait_settled(None, 0.0, -1))
        if self.fixture_mode == "command":
            self.table.mount(mount)
        elif self.fixture_mode == "prompt":  # 'fixed': mounted before the run, check() allows one mount only
            self.prompt(f"rig {self.name}: mount the unit {mount_label(mount)} and press Enter ")
        self._mounted = True
        self.state.mount = np.asarray(mount).tolist()
        parts.append(self._frame(self.stream.take(until_host_t=time.monotonic()), -1))
        return _concat(parts)

    def _wait_settled(self, angle: float | None, rate: float, step: int) -> pd.DataFrame:
        """Record (label ``step``) until the read-back angle (if given) and rate are within tolerance."""
        parts, waited = [], 0
        while True:
            block = self.stream.take(self.chunk)
            parts.append(self._frame(block, step))
            waited += len(block.t)
            a, r = self.state.table_angle, self.state.table_rate
            angle_ok = angle is None or abs(wrap_pi(a - angle)) <= self.angle_tol
            if angle_ok and abs(r - rate) <= self.rate_tol:
                break
            if waited > self.settle_timeout_s * self.fs:
                target = f"angle {np.degrees(angle):.4f}° " if angle is not None else ""
                raise RigError(f"{self.table.where}: table did not settle at {target}rate {np.degrees(rate):.4f} °/s "
                               f"within {self.settle_timeout_s:g} s (read back {np.degrees(a):.4f}°, "
                               f"{np.degrees(r):.4f} °/s)")
        parts.append(self._frame(self.stream.take(until_host_t=time.monotonic()), step))  # frames of the motion
        return _concat(parts)

    def _record(self, n: int, step: int, each_chunk: Callable[[Block], bool] | None = None) -> pd.DataFrame:
        """``n`` samples labelled ``step`` (or until ``each_chunk`` returns True when ``n`` is 0)."""
        parts, got = [], 0
        while (n and got < n) or (not n):
            block = self.stream.take(min(self.chunk, n - got) if n else self.chunk)
            parts.append(self._frame(block, step))
            got += len(block.t)
            if each_chunk is not None and each_chunk(block):
                break
        return _concat(parts)

    def _soak(self, p: PlannedStep, index: int) -> pd.DataFrame:
        """Record until the unit temperature settles (slope over the window below the tolerance)."""
        tol = float(p.extra.get("settle_tol_c_per_min", 0.05))
        window = float(p.extra.get("settle_window_s", 120.0))
        times, temps = [], []
        t0 = self.stream.next_sample / self.fs

        def settled(block: Block) -> bool:
            if "temp" not in block.columns:
                raise RigError(f"{self.stream.where}: a soak needs the unit temperature (field 'temp') in the frames")
            times.append(float(block.t[-1]))
            temps.append(float(np.mean(block.columns["temp"])))
            elapsed = times[-1] - t0
            if elapsed > p.duration_s:
                raise RigError(f"unit temperature did not settle within {p.duration_s:.0f} s "
                               f"(still {temps[-1]:.2f} °C, chamber {self.state.air_c:.2f} °C)")
            if elapsed < window or abs(self.state.air_c - p.temperature_c) > self.air_tol_c:
                return False
            k = int(np.searchsorted(times, times[-1] - window))
            slope = abs(temps[-1] - temps[k]) / max(times[-1] - times[k], 1e-9) * 60.0
            return slope < tol

        return self._record(0, index, settled)

    def _ramp(self, p: PlannedStep, index: int) -> pd.DataFrame:
        """Record ``duration_s`` while stepping the chamber setpoint along the ramp from the host."""
        rate = float(p.extra.get("ramp_rate_c_per_min", 0.0))
        to_c = float(p.extra.get("ramp_to_c", p.temperature_c))
        t0 = self.stream.next_sample / self.fs

        def follow(block: Block) -> bool:
            sp = p.temperature_c + rate * (float(block.t[-1]) - t0) / 60.0
            sp = min(sp, to_c) if rate > 0 else max(sp, to_c)
            if abs(sp - self.state.chamber_target_c) >= 0.05:
                self._setpoint(sp)
            return False

        return self._record(max(1, int(round(p.duration_s * self.fs))), index, follow)

    def _frame(self, block: Block, step: int) -> pd.DataFrame:
        """Samples of ``block`` with the table read-back (polled now) and the interlock checked."""
        trouble = self.table.interlock()
        if trouble is not None:
            raise RigError(f"{self.table.where}: interlock reported by the controller: {trouble}")
        angle, rate = self.table.angle(), self.table.rate()
        self.state.table_angle, self.state.table_rate = angle, rate
        if self.chamber is not None:
            self.state.air_c = self.chamber.temperature()
        n = len(block.t)
        data = {"t": block.t, "step": np.full(n, step, dtype=np.int64), **block.columns}
        if n:
            data["table_angle"] = wrap_2pi(angle - rate * (block.t[-1] - block.t))
            data["table_rate"] = np.full(n, rate)
            if "temp" in block.columns:
                self.state.unit_c = float(block.columns["temp"][-1])
        else:
            data.update(table_angle=np.zeros(0), table_rate=np.zeros(0))
        return pd.DataFrame(data)


def _concat(parts: list[pd.DataFrame]) -> pd.DataFrame:
    """The non-empty sample frames of ``parts`` in order (an empty frame if none)."""
    full = [x for x in parts if len(x)]
    return pd.concat(full, ignore_index=True) if full else pd.DataFrame()
