"""Test sequences: declarative, composable, serialisable steps for the turntable and chamber.

A :class:`Sequence` is a list of steps (:class:`Hold`, :class:`Rotate`, :class:`Index`,
:class:`Carousel`, :class:`Soak`, :class:`Ramp`, :class:`Free`, and :class:`Repeat` to nest them). It is
shown to the user (:meth:`Sequence.describe`) before it runs and expands
(:meth:`Sequence.expand`) into :class:`PlannedStep` records with absolute mount, table angle,
rate and chamber setpoint, which the runner hands to a rig one at a time.

SI inside: angles rad, rates rad/s (positive clockwise seen from above, i.e. about the
table's down axis), temperatures °C, times s. ``mount`` is the body->table-top rotation, given
as a name (``"x-up"``: body x along the table's up direction, ... ``"z-down"`` = identity),
a 3x3 matrix, or :func:`mount_from_euler`.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any, Union

import numpy as np
from scipy.spatial.transform import Rotation

from workbench.angles import wrap_2pi as _wrap
from workbench.errors import RigLimitError

_NAMED_MOUNTS = {
    "z-down": Rotation.identity(),
    "z-up": Rotation.from_euler("x", 180, degrees=True),
    "x-up": Rotation.from_euler("y", 90, degrees=True),
    "x-down": Rotation.from_euler("y", -90, degrees=True),
    "y-up": Rotation.from_euler("x", -90, degrees=True),
    "y-down": Rotation.from_euler("x", 90, degrees=True),
}
MOUNT_NAMES = tuple(_NAMED_MOUNTS)
Mount = Union[str, list, np.ndarray, None]


def mount_matrix(mount: Mount) -> np.ndarray:
    """The 3x3 body->table-top rotation of a mount given by name or matrix."""
    if isinstance(mount, str):
        if mount not in _NAMED_MOUNTS:
            raise RigLimitError(f"unknown mount {mount!r} (expected one of {', '.join(MOUNT_NAMES)} or a 3x3 matrix)")
        return _NAMED_MOUNTS[mount].as_matrix()
    try:
        m = np.asarray(mount, float)
    except (TypeError, ValueError):  # a ragged list, text inside, a mapping
        raise RigLimitError("mount: not a 3x3 rotation matrix") from None
    if m.shape != (3, 3) or not np.allclose(m @ m.T, np.eye(3), atol=1e-6) or np.linalg.det(m) < 0:
        raise RigLimitError("mount: not a 3x3 rotation matrix")
    return m


def mount_from_euler(seq: str, angles_deg: Iterable[float], base: str = "z-down") -> list:
    """A mount: ``base`` followed by body-fixed Euler rotations (scipy ``seq``, degrees)."""
    r = Rotation.from_matrix(mount_matrix(base)) * Rotation.from_euler(seq, list(angles_deg), degrees=True)
    return r.as_matrix().tolist()


def mount_label(mount: Mount) -> str:
    """Short display name of a mount."""
    if isinstance(mount, str):
        return mount
    m = mount_matrix(mount)
    for name, r in _NAMED_MOUNTS.items():
        if np.allclose(r.as_matrix(), m, atol=1e-9):
            return name
    up = -m[2]  # body-frame components of the table's up direction
    axis = int(np.argmax(np.abs(up)))
    tilt = np.degrees(np.arccos(min(1.0, abs(up[axis]))))
    return f"{'xyz'[axis]}-{'up' if up[axis] > 0 else 'down'}{f' tilted {tilt:.0f}°' if tilt > 0.5 else ''}"


@dataclass(frozen=True)
class Hold:
    """Static hold at ``mount`` and absolute ``table_angle`` (rad) for ``dwell_s``."""

    mount: Mount = None
    table_angle: float | None = None
    dwell_s: float = 60.0
    label: str = ""


@dataclass(frozen=True)
class Rotate:
    """Constant table rate ``rate`` (rad/s) at ``mount`` for ``revolutions`` or ``duration_s``."""

    mount: Mount = None
    rate: float = 0.0
    revolutions: float | None = 1.0
    duration_s: float | None = None
    label: str = ""


@dataclass(frozen=True)
class Index:
    """Turn the table by ``angle`` (rad, from where it is) at ``index_rate``, then hold ``dwell_s``."""

    angle: float = np.pi
    dwell_s: float = 60.0
    index_rate: float = np.radians(30.0)
    label: str = ""


@dataclass(frozen=True)
class Carousel:
    """Continuous rotation at ``rate`` (rad/s) for ``laps`` whole laps (north-finding carousel)."""

    mount: Mount = None
    rate: float = np.radians(10.0)
    laps: int = 1
    label: str = ""


@dataclass(frozen=True)
class Soak:
    """Chamber to ``setpoint_c``; hold static until the unit's own temperature settles.

    Settled = the unit temperature changes by less than ``settle_tol_c_per_min`` over the
    last ``settle_window_s``; the step fails after ``max_s``.
    """

    setpoint_c: float = 23.0
    mount: Mount = None
    table_angle: float | None = None
    settle_tol_c_per_min: float = 0.05
    settle_window_s: float = 120.0
    max_s: float = 4 * 3600.0
    label: str = ""


@dataclass(frozen=True)
class Ramp:
    """Chamber ramp to ``to_c`` at ``rate_c_per_min``, the unit static at ``mount``.

    With ``positions`` (a list of ``[mount, table_angle]``) and ``dwell_s``, the unit indexes
    through the positions in turn, ``dwell_s`` each, until the ramp ends.
    """

    to_c: float = 23.0
    rate_c_per_min: float = 1.0
    mount: Mount = None
    table_angle: float | None = None
    positions: list | None = None
    dwell_s: float | None = None
    label: str = ""


@dataclass(frozen=True)
class Free:
    """Motion by hand for ``duration_s``: no table, no known attitude.

    The unit is turned (or held) by a person; only its own sensors know its attitude, so an
    analysis of a ``free`` step takes gravity from the accelerometer's still stretches
    (:mod:`workbench.analysis.stationarity`) and never a table angle or mount. A rig leaves the
    unit where it is for the step; the kind is for recordings made by hand (an import profile without ``sections`` makes
    the whole recording one ``free`` step).
    """

    duration_s: float = 60.0
    label: str = ""


@dataclass(frozen=True)
class Repeat:
    """``steps`` repeated ``count`` times."""

    steps: list = field(default_factory=list)
    count: int = 1
    label: str = ""


STEP_TYPES = {cls.__name__: cls for cls in (Hold, Rotate, Index, Carousel, Soak, Ramp, Free, Repeat)}
Step = Union[Hold, Rotate, Index, Carousel, Soak, Ramp, Free, Repeat]


@dataclass(frozen=True)
class PlannedStep:
    """One expanded step, absolute: what the rig is asked to do (see ``workbench.session``)."""

    kind: str  # static | rate | index | carousel | soak | ramp | free
    mount: np.ndarray
    table_angle: float  # rad at the step start
    table_rate: float  # rad/s commanded (0 when static)
    duration_s: float  # planned; a soak's is its upper bound
    temperature_c: float | None  # chamber setpoint during the step
    label: str = ""
    extra: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"kind": self.kind, "mount": np.asarray(self.mount).tolist(), "table_angle": self.table_angle,
                "table_rate": self.table_rate, "duration_s": self.duration_s,
                "temperature_c": self.temperature_c, "label": self.label, **self.extra}


def _step_to_dict(step: Step) -> dict:
    d: dict[str, Any] = {"type": type(step).__name__}
    for f in fields(step):
        v = getattr(step, f.name)
        if f.name == "steps":
            v = [_step_to_dict(s) for s in v]
        elif isinstance(v, np.ndarray):
            v = v.tolist()
        d[f.name] = v
    return d


def step_from_dict(d: Mapping) -> Step:
    """Build a step from its JSON dict (``{"type": "Hold", ...}``)."""
    d = dict(d)
    kind = d.pop("type", None)
    if kind not in STEP_TYPES:
        raise RigLimitError(f"sequence: unknown step type {kind!r} (expected one of {', '.join(STEP_TYPES)})")
    if kind == "Repeat":
        d["steps"] = [step_from_dict(s) for s in d.get("steps", [])]
    try:
        return STEP_TYPES[kind](**d)
    except TypeError as exc:
        raise RigLimitError(f"sequence: step {kind}: {exc}") from None


@dataclass(frozen=True)
class Sequence:
    """A named list of steps with the options that produced it (see the module docstring)."""

    name: str
    steps: list = field(default_factory=list)
    options: Mapping[str, Any] = field(default_factory=dict)
    start_temperature_c: float | None = None

    def expand(self) -> list[PlannedStep]:
        """Flatten into absolute :class:`PlannedStep` records (mount and angle carried over)."""
        state = {"mount": np.eye(3), "angle": 0.0, "temp": self.start_temperature_c}
        out: list[PlannedStep] = []
        self._expand(self.steps, state, out)
        if not out:
            raise RigLimitError(f"sequence {self.name}: no steps")
        return out

    def _expand(self, steps: list, st: dict, out: list[PlannedStep]) -> None:
        for s in steps:
            if isinstance(s, Repeat):
                if s.count < 1:
                    raise RigLimitError(f"sequence {self.name}: Repeat count {s.count} < 1")
                for _ in range(s.count):
                    self._expand(s.steps, st, out)
                continue
            if getattr(s, "mount", None) is not None:
                st["mount"] = mount_matrix(s.mount)
            if getattr(s, "table_angle", None) is not None:
                st["angle"] = float(s.table_angle)
            if isinstance(s, Hold):
                _positive(self.name, "Hold.dwell_s", s.dwell_s)
                out.append(PlannedStep("static", st["mount"], st["angle"], 0.0, s.dwell_s, st["temp"], s.label))
            elif isinstance(s, (Rotate, Carousel)):
                if s.rate == 0:
                    raise RigLimitError(f"sequence {self.name}: {type(s).__name__} with zero rate")
                revs = s.laps if isinstance(s, Carousel) else s.revolutions
                dur = s.duration_s if isinstance(s, Rotate) and s.duration_s else abs(revs * 2 * np.pi / s.rate)
                _positive(self.name, f"{type(s).__name__} duration", dur)
                kind = "carousel" if isinstance(s, Carousel) else "rate"
                extra = {"revolutions": float(abs(s.rate) * dur / (2 * np.pi))}
                out.append(PlannedStep(kind, st["mount"], st["angle"], float(s.rate), dur, st["temp"], s.label, extra))
                st["angle"] = _wrap(st["angle"] + s.rate * dur)
            elif isinstance(s, Index):
                _positive(self.name, "Index.index_rate", s.index_rate)
                dur = abs(s.angle) / s.index_rate
                rate = float(np.sign(s.angle) * s.index_rate)
                out.append(PlannedStep("index", st["mount"], st["angle"], rate, dur, st["temp"], s.label,
                                       {"index_angle": float(s.angle)}))
                st["angle"] = _wrap(st["angle"] + s.angle)
                if s.dwell_s > 0:
                    out.append(PlannedStep("static", st["mount"], st["angle"], 0.0, s.dwell_s, st["temp"], s.label))
            elif isinstance(s, Soak):
                st["temp"] = float(s.setpoint_c)
                out.append(PlannedStep("soak", st["mount"], st["angle"], 0.0, s.max_s, st["temp"], s.label,
                                       {"settle_tol_c_per_min": s.settle_tol_c_per_min,
                                        "settle_window_s": s.settle_window_s}))
            elif isinstance(s, Ramp):
                self._expand_ramp(s, st, out)
            elif isinstance(s, Free):
                _positive(self.name, "Free.duration_s", s.duration_s)
                out.append(PlannedStep("free", np.eye(3), 0.0, 0.0, float(s.duration_s), st["temp"], s.label))
            else:
                raise RigLimitError(f"sequence {self.name}: unknown step {s!r}")

    def _expand_ramp(self, s: Ramp, st: dict, out: list[PlannedStep]) -> None:
        if st["temp"] is None:
            raise RigLimitError(f"sequence {self.name}: Ramp needs a start temperature (a Soak before it)")
        _positive(self.name, "Ramp.rate_c_per_min", s.rate_c_per_min)
        start = st["temp"]
        total = abs(s.to_c - start) / s.rate_c_per_min * 60.0
        _positive(self.name, "Ramp duration (to_c equals the current setpoint)", total)
        positions = s.positions or [[None, None]]
        dwell = s.dwell_s or total
        n = int(np.ceil(total / dwell - 1e-9))
        direction = 1.0 if s.to_c > start else -1.0
        for k in range(n):
            mount, angle = positions[k % len(positions)]
            if mount is not None:
                st["mount"] = mount_matrix(mount)
            if angle is not None:
                st["angle"] = float(angle)
            t0, t1 = k * dwell, min(total, (k + 1) * dwell)
            sp0 = start + direction * s.rate_c_per_min * t0 / 60.0
            out.append(PlannedStep("ramp", st["mount"], st["angle"], 0.0, t1 - t0, sp0, s.label,
                                   {"ramp_to_c": float(s.to_c), "ramp_rate_c_per_min": float(direction * s.rate_c_per_min),
                                    "branch": "up" if direction > 0 else "down"}))
        st["temp"] = float(s.to_c)

    @property
    def duration_s(self) -> float:
        """Planned total duration, s (soaks counted at their upper bound)."""
        return float(sum(p.duration_s for p in self.expand()))

    def describe(self) -> list[dict]:
        """Rows for display: index, kind, mount, angle (°), rate (°/s), duration (s), setpoint (°C)."""
        return [{"index": i, "kind": p.kind, "label": p.label, "mount": mount_label(p.mount),
                 "table_angle_deg": round(float(np.degrees(p.table_angle)), 3),
                 "table_rate_dps": round(float(np.degrees(p.table_rate)), 4),
                 "duration_s": round(float(p.duration_s), 3), "temperature_c": p.temperature_c}
                for i, p in enumerate(self.expand())]

    def to_dict(self) -> dict:
        return {"name": self.name, "options": dict(self.options), "start_temperature_c": self.start_temperature_c,
                "steps": [_step_to_dict(s) for s in self.steps]}

    def to_json(self) -> str:
        """JSON text of the sequence (steps as ``{"type": ..., fields}``)."""
        return json.dumps(self.to_dict(), indent=1, default=lambda o: o.tolist())

    @classmethod
    def from_dict(cls, d: Mapping) -> Sequence:
        return cls(d["name"], [step_from_dict(s) for s in d.get("steps", [])], d.get("options", {}),
                   d.get("start_temperature_c"))

    @classmethod
    def from_json(cls, text: str) -> Sequence:
        return cls.from_dict(json.loads(text))


def _positive(name: str, what: str, value: float) -> None:
    if not (value is not None and np.isfinite(value) and value > 0):
        raise RigLimitError(f"sequence {name}: {what} must be positive (got {value})")


def with_options(seq: Sequence, **options) -> Sequence:
    """A copy of ``seq`` with ``options`` recorded."""
    return replace(seq, options={**seq.options, **options})


__all__ = ["Hold", "Rotate", "Index", "Carousel", "Soak", "Ramp", "Free", "Repeat", "Sequence", "PlannedStep",
           "mount_matrix", "mount_from_euler", "mount_label", "MOUNT_NAMES", "step_from_dict"]
