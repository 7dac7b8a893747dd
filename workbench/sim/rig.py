"""The simulated rig: a level single-axis turntable with a mounting fixture, in a climatic chamber.

It turns a :class:`~workbench.sequence.PlannedStep` into the true motion and environment of
the unit (table angle and rate, body-frame angular rate, specific force and magnetic field,
air and unit temperature) and passes them through the virtual IMU. The truth uses the site's
latitude: normal gravity and Earth rate in NED, and the site's magnetic field.

Motion between steps (remounting, moving to a new table angle, accelerating to a rate,
settling) is recorded as transition samples labelled ``step = -1``. Each static step carries a
random fixture/positioning error (a small rotation, 1-sigma ``positioning_error``) that the
session does not know, as on a real table.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from workbench.angles import wrap_2pi, wrap_pi
from workbench.earth import earth_rate_ned, normal_gravity
from workbench.errors import RigError
from workbench.motion import RigState
from workbench.rigconfig import RigConfig, check_plan
from workbench.sequence import PlannedStep
from workbench.session import StepRecord
from workbench.sim.filters import first_order_lag

_SOAK_CHUNK_S = 60.0
_STEADY_BLOCK = 64  # rows rotated at once for a steady segment (the matrix product is row-wise exact)


class SimRig:
    """Simulated turntable + chamber driving a :class:`~workbench.sim.sensor.VirtualIMU`."""

    driver = "sim"

    def __init__(self, config: RigConfig, truth, seed: int, state: RigState | None = None, imperfections=None):
        from workbench.sim.sensor import VirtualIMU

        self.config = config
        self.name = config.name
        self.site = config.site
        self.truth = truth
        self.fs = float(truth.sample_rate_hz)
        self.seed = int(seed)
        self.imu = VirtualIMU(truth, seed, imperfections)
        self._table = imperfections if imperfections is not None and imperfections.table else None
        self.rng = np.random.default_rng([self.seed, 7])
        c0 = config.chamber.initial_c
        self.state = state or RigState(air_c=c0, unit_c=c0, chamber_target_c=c0,
                                       chamber_rate_c_per_min=config.chamber.max_ramp_c_per_min,
                                       mount=np.eye(3).tolist())
        if self.state.imu is not None:
            self.imu.restore(self.state.imu)
        if self.state.rng is not None:
            self.rng.bit_generator.state = self.state.rng
        lat = self.site.latitude
        self._g = float(normal_gravity(lat, self.site.height_m))
        self._wie = earth_rate_ned(lat)
        self._az0 = self.site.table_zero_azimuth or 0.0
        self._mag = config.magnetic_field_ned if "mag" in truth.triads else None

    # -- interface shared with real rigs ---------------------------------------------
    def check(self, plan: list[PlannedStep]) -> None:
        """Raise RigLimitError if any planned step is outside the rig's limits (or the memory for its record)."""
        check_plan(plan, self.config, self.fs)

    def identify(self) -> dict:
        """Identity and state, without moving anything."""
        return {"driver": self.driver, "name": self.name, "table_angle_deg": float(np.degrees(self.state.table_angle)),
                "air_c": self.state.air_c, "unit_c": self.state.unit_c}

    def safe(self) -> None:
        """Stop the table and send the chamber to its safe setpoint (instant in simulation)."""
        self.state.table_rate = 0.0
        self.state.chamber_target_c = self.config.chamber.safe_c

    def close(self) -> None:
        """Nothing to release in simulation."""

    def perform(self, planned: PlannedStep, index: int) -> tuple[pd.DataFrame, StepRecord]:
        """Run one planned step: the transition into it (step -1) and the step itself.

        Returns the samples (transition and step, in time order) and the step's record.
        """
        parts = [self._transition(planned)]  # columns of each part, joined into one frame at the end
        st = self.state
        t_start = st.sample / self.fs
        if planned.temperature_c is not None and planned.kind in ("soak", "ramp"):
            st.chamber_target_c = planned.extra.get("ramp_to_c", planned.temperature_c)
            st.chamber_rate_c_per_min = abs(planned.extra.get("ramp_rate_c_per_min",
                                                              self.config.chamber.max_ramp_c_per_min))
        error = self._fixture_error()
        start_angle = st.table_angle
        if planned.kind == "soak":
            parts.append(self._soak(planned, index, error))
        elif planned.kind == "index":
            parts.append(self._index_move(planned, index, error))
        else:
            n = max(1, int(round(planned.duration_s * self.fs)))
            rate = planned.table_rate if planned.kind in ("rate", "carousel") else 0.0
            parts.append(self._columns(n, index, planned.mount, rate_profile=np.full(n, rate), error=error))
        samples = _frame(parts)
        st.imu, st.rng = self.imu.state(), self.rng.bit_generator.state
        t_end = st.sample / self.fs
        record = StepRecord(index, planned.kind, t_start, t_end - 0.5 / self.fs, np.asarray(planned.mount),
                            float(start_angle), float(planned.table_rate), planned.temperature_c, planned.label,
                            dict(planned.extra))
        return samples, record

    # -- hook for the hardware-in-the-loop simulator (workbench/sim/hil.py) -----------
    def advance(self, rate_profile: np.ndarray, new_fixture_error: bool = False) -> pd.DataFrame:
        """Simulate ``len(rate_profile)`` samples at the current mount (step label -1).

        ``rate_profile``: table rate rad/s per sample; ``new_fixture_error`` draws a fresh
        fixture/positioning error (as at the start of a step) that is kept until the next draw.
        Returns the samples with the true table angle and rate; updates :attr:`state`.
        """
        if new_fixture_error or not hasattr(self, "_hil_error"):
            self._hil_error = self._fixture_error()
        rates = np.asarray(rate_profile, float)
        return self._segment(len(rates), -1, self.state.mount, rate_profile=rates, error=self._hil_error)

    # -- motion ----------------------------------------------------------------------
    def _fixture_error(self) -> Rotation:
        sigma = self.config.turntable.positioning_error
        return Rotation.from_rotvec(self.rng.normal(0.0, sigma, 3))

    def _transition(self, planned: PlannedStep) -> dict[str, np.ndarray]:
        """Decelerate, remount, move to the step's angle, accelerate to its rate, settle (step -1)."""
        st, tt = self.state, self.config.turntable
        profiles = []
        if st.table_rate != 0.0 and not (planned.kind in ("rate", "carousel") and planned.table_rate == st.table_rate):
            profiles.append(_ramp_rate(st.table_rate, 0.0, tt.max_accel, self.fs))
        mount_now = np.asarray(st.mount)
        target_rate = planned.table_rate if planned.kind in ("rate", "carousel") else 0.0
        moving_angle = planned.kind in ("static", "soak", "ramp", "index")
        if moving_angle:
            delta = wrap_pi(planned.table_angle - st.table_angle)
            if abs(delta) > 1e-9:
                profiles.append(_move(delta, min(tt.max_rate, np.radians(60.0)), tt.max_accel, self.fs))
        if target_rate != 0.0 and st.table_rate != target_rate:
            profiles.append(_ramp_rate(0.0, target_rate, tt.max_accel, self.fs))
        settle = np.full(int(round(tt.settle_s * self.fs)), target_rate)
        rate = np.concatenate([*profiles, settle]) if profiles or len(settle) else np.zeros(0)
        if not np.allclose(mount_now, planned.mount):
            mount_now = np.asarray(planned.mount)  # remounted by hand: instantaneous in simulation
        if len(rate) == 0:
            return {}
        return self._columns(len(rate), -1, mount_now, rate_profile=rate, error=Rotation.identity())

    def _index_move(self, planned: PlannedStep, index: int, error: Rotation) -> dict[str, np.ndarray]:
        angle = planned.extra["index_angle"]
        rate = _move(angle, abs(planned.table_rate), self.config.turntable.max_accel, self.fs)
        return self._columns(len(rate), index, planned.mount, rate_profile=rate, error=error)

    def _soak(self, planned: PlannedStep, index: int, error: Rotation) -> dict[str, np.ndarray]:
        tol = planned.extra.get("settle_tol_c_per_min", 0.05)
        window = planned.extra.get("settle_window_s", 120.0)
        chunks, elapsed = [], 0.0
        n = int(round(_SOAK_CHUNK_S * self.fs))
        history_t, history_c = [], []
        while True:
            chunk = self._columns(n, index, planned.mount, rate_profile=np.zeros(n), error=error)
            chunks.append(chunk)
            elapsed += _SOAK_CHUNK_S
            history_t.append(chunk["t"][-1])
            history_c.append(float(chunk["temp"][-int(self.fs):].mean()))
            if elapsed >= window and abs(self.state.air_c - planned.temperature_c) < 1e-9:
                k = int(np.ceil(window / _SOAK_CHUNK_S))
                if len(history_c) > k:
                    slope = abs(history_c[-1] - history_c[-1 - k]) / (history_t[-1] - history_t[-1 - k]) * 60
                    if slope < tol:
                        break
            if elapsed >= planned.duration_s:
                raise RigError(f"rig {self.name}: step {index} (soak to {planned.temperature_c:.1f} °C): "
                               f"unit temperature did not settle within {planned.duration_s:.0f} s "
                               f"(still {self.state.unit_c:.2f} °C)")
        return {c: np.concatenate([chunk[c] for chunk in chunks]) for c in chunks[0]}

    def _segment(self, n: int, step: int, mount, rate_profile: np.ndarray, error: Rotation) -> pd.DataFrame:
        """Simulate ``n`` samples with the given table-rate profile (rad/s per sample), as a frame."""
        return pd.DataFrame(self._columns(n, step, mount, rate_profile, error))

    def _columns(self, n: int, step: int, mount, rate_profile: np.ndarray, error: Rotation) -> dict[str, np.ndarray]:
        """Simulate ``n`` samples with the given table-rate profile (rad/s per sample): {column: (n,) array}."""
        st, fs = self.state, self.fs
        k = st.sample + np.arange(n)
        t = k / fs
        # table angle: trapezoidal integration of the rate profile from the current angle
        prev = np.concatenate([[st.table_rate], rate_profile[:-1]])
        angle = st.table_angle + np.cumsum(0.5 * (prev + rate_profile)) / fs
        # truth in body frame: C_bn = Rz(az0 + angle) @ E @ mount, so v_b = (E mount)^T Rz^T v_n
        m_true = error.as_matrix() @ np.asarray(mount)
        # at a constant table angle and rate (a static step) every row is the same: rotate one block
        steady = n > _STEADY_BLOCK and angle[0] == angle[-1] and (angle == angle[0]).all() \
            and (rate_profile == rate_profile[0]).all()
        rows = _STEADY_BLOCK if steady else n
        psi = self._az0 + angle[:rows]
        c, s = np.cos(psi), np.sin(psi)

        def ned_to_body(v_ned: np.ndarray) -> np.ndarray:
            v = np.broadcast_to(v_ned, (rows, 3))
            vt = np.stack([c * v[:, 0] + s * v[:, 1], -s * v[:, 0] + c * v[:, 1], v[:, 2]], axis=1)
            body = vt @ m_true  # row-vector form of m_true^T @ vt
            return np.repeat(body[:1], n, axis=0) if steady else body

        if self._table is not None:
            omega_b, f_b, m_b = self._imperfect_table(angle[:rows], rate_profile[:rows], m_true, n if steady else None)
        else:
            omega_ned = np.empty((rows, 3))
            omega_ned[:] = self._wie
            omega_ned[:, 2] += rate_profile[:rows]
            omega_b = ned_to_body(omega_ned)
            f_b = ned_to_body(np.array([0.0, 0.0, -self._g]))
            m_b = ned_to_body(self._mag) if self._mag is not None else None
        air, unit = self._temperatures(n)
        out = self.imu.measure(omega_b, f_b, m_b, unit)
        res = self.config.turntable.encoder_resolution
        data = {"t": t, "step": np.full(n, step, dtype=np.int64)}
        data.update({c: out["gyro"][:, i] for i, c in enumerate(("gx", "gy", "gz"))})
        data.update({c: out["accel"][:, i] for i, c in enumerate(("ax", "ay", "az"))})
        if out.get("mag") is not None:
            data.update({c: out["mag"][:, i] for i, c in enumerate(("mx", "my", "mz"))})
        data["temp"] = out["temp"]
        data["table_angle"] = wrap_2pi(np.round(angle / res) * res)
        data["table_rate"] = rate_profile
        st.sample += n
        st.table_angle = wrap_2pi(float(angle[-1]))
        st.table_rate = float(rate_profile[-1])
        st.mount = np.asarray(mount).tolist()
        return data

    def _imperfect_table(self, angle: np.ndarray, rate: np.ndarray, m_true: np.ndarray, repeat: int | None):
        """Body-frame angular rate, specific force and field on a table with indexing error, wobble, axis tilt.

        ``angle``/``rate``: encoder angle (rad) and commanded rate (rad/s) per row. The platform's
        attitude is ``C_np = A W(theta) Rz(az0 + theta + e(theta))`` with ``A`` the fixed axis tilt and
        ``W`` the wobble (both about the base x axis); its rate in the platform frame is
        ``Rz^T (W^T A^T w_ie + eps' x) + psi' z`` with ``eps' = w cos(theta) rate`` and
        ``psi' = rate (1 + a cos(theta))``. ``repeat``: rows to repeat the first row to (a steady step).
        """
        imp = self._table
        psi = self._az0 + angle + imp.table_indexing_error * np.sin(angle)
        psi_dot = rate * (1.0 + imp.table_indexing_error * np.cos(angle))
        eps = imp.table_axis_tilt + imp.table_wobble * np.sin(angle)
        eps_dot = imp.table_wobble * np.cos(angle) * rate
        ce, se, c, s = np.cos(eps), np.sin(eps), np.cos(psi), np.sin(psi)

        def to_platform(v: np.ndarray, extra_x=0.0, extra_z=0.0) -> np.ndarray:
            v = np.broadcast_to(v, (len(angle), 3))
            x, y, z = v[:, 0] + extra_x, ce * v[:, 1] + se * v[:, 2], -se * v[:, 1] + ce * v[:, 2]
            body = np.stack([c * x + s * y, -s * x + c * y, z + extra_z], axis=1) @ m_true
            return np.repeat(body[:1], repeat, axis=0) if repeat else body

        omega_b = to_platform(self._wie, eps_dot, psi_dot)
        f_b = to_platform(np.array([0.0, 0.0, -self._g]))
        m_b = to_platform(np.asarray(self._mag, float)) if self._mag is not None else None
        return omega_b, f_b, m_b

    def _temperatures(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Air temperature (moving to the chamber target at its ramp rate) and the unit's lag."""
        st = self.state
        dt = 1.0 / self.fs
        step = st.chamber_rate_c_per_min / 60.0 * dt * np.arange(1, n + 1)
        if st.chamber_target_c >= st.air_c:
            air = np.minimum(st.air_c + step, st.chamber_target_c)
        else:
            air = np.maximum(st.air_c - step, st.chamber_target_c)
        tau = float(self.truth.thermal_time_constant_s)
        unit = first_order_lag(air, float(np.exp(-dt / tau)), st.unit_c)
        st.air_c, st.unit_c = float(air[-1]), float(unit[-1])
        return air, unit


def _frame(parts: list[dict[str, np.ndarray]]) -> pd.DataFrame:
    """One frame of the samples of ``parts`` ({column: array}, in time order; empty ones left out).

    The frame holds the arrays as they are (one block per column, not copied into one): the
    runner writes them to the step's part and joins the steps' columns into the session's.
    """
    parts = [p for p in parts if p]
    if len(parts) == 1:
        return pd.DataFrame(parts[0], copy=False)
    return pd.DataFrame({c: np.concatenate([p[c] for p in parts]) for c in parts[0]}, copy=False)


def _ramp_rate(r0: float, r1: float, accel: float, fs: float) -> np.ndarray:
    """Rate profile (rad/s per sample) from ``r0`` to ``r1`` at the acceleration limit."""
    n = max(1, int(np.ceil(abs(r1 - r0) / accel * fs)))
    return np.linspace(r0, r1, n + 1)[1:]


def _move(delta: float, max_rate: float, accel: float, fs: float) -> np.ndarray:
    """Rate profile of a rest-to-rest move by ``delta`` rad (trapezoid or triangle), exact in angle."""
    if abs(delta) < 1e-12:
        return np.zeros(1)
    peak = min(max_rate, np.sqrt(abs(delta) * accel))
    t_acc = peak / accel
    t_total = abs(delta) / peak + t_acc
    n = max(2, int(np.ceil(t_total * fs)))
    t = np.arange(1, n + 1) / fs
    scale = t_total / (n / fs)
    tt = t * scale
    prof = np.minimum.reduce([tt / t_acc, np.ones(n), (t_total - tt) / t_acc]).clip(0.0, 1.0)
    prev = np.concatenate([[0.0], prof[:-1]])
    area = np.sum(0.5 * (prev + prof)) / fs
    return np.sign(delta) * prof * abs(delta) / area


move_profile = _move  # public names for the real-rig drivers and the hardware-in-the-loop simulator
ramp_profile = _ramp_rate
