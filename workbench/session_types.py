"""Value types and constants of the session format (``workbench-session/1``, ``docs/formats.md``).

:class:`Site` (where the rig stands; degrees as in the file, radians via properties),
:class:`StepRecord` (one recorded step: times s, table angle rad, table rate rad/s, ``mount``
3x3 body->table-top), the column lists, the step kinds and the ``flags`` bits
(:data:`FLAG_SATURATED`, :data:`FLAG_REPEATED`, per triad). Re-exported by :mod:`workbench.session`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from workbench.earth import normal_gravity
from workbench.errors import SessionError
from workbench.values import ACCEL, GYRO, MAG

FORMAT = "workbench-session/1"
STEP_LOG = "steps.jsonl"  # an unfinished recording's completed steps, one JSON object a line (runner.py)
STEP_KINDS = ("static", "rate", "index", "carousel", "soak", "ramp", "drive", "free")  # free: by hand, no table
REQUIRED_COLUMNS = ["t", "step", *GYRO, *ACCEL]
OPTIONAL_COLUMNS = [*MAG, "temp", "table_angle", "table_rate", "odo_distance", "flags"]
# bits of the optional ``flags`` column (imported recordings): a set bit leaves the sample out of that triad's fits
FLAG_SATURATED = {"gyro": 1, "accel": 2, "mag": 4}  # a value at the stream's declared range
FLAG_REPEATED = {"gyro": 32, "accel": 16, "mag": 8}  # a stale read: the sensor had not updated


@dataclass(frozen=True)
class Site:
    """Where the rig stands. Angles stored in degrees as in the file; radians via properties."""

    latitude_deg: float
    longitude_deg: float = 0.0
    height_m: float = 0.0
    table_zero_azimuth_deg: float | None = None
    field_norm_ut: float | None = None  # reference magnetic-field magnitude at the rig, µT (None = unknown)

    @property
    def latitude(self) -> float:
        """Geodetic latitude, rad."""
        return float(np.radians(self.latitude_deg))

    @property
    def table_zero_azimuth(self) -> float | None:
        """Azimuth of the table's zero direction clockwise from true north, rad (None = unknown)."""
        return None if self.table_zero_azimuth_deg is None else float(np.radians(self.table_zero_azimuth_deg))

    @property
    def gravity(self) -> float:
        """Normal gravity magnitude at the site, m/s^2."""
        return float(normal_gravity(self.latitude, self.height_m))

    def to_dict(self) -> dict:
        out = {"latitude_deg": self.latitude_deg, "longitude_deg": self.longitude_deg,
               "height_m": self.height_m, "table_zero_azimuth_deg": self.table_zero_azimuth_deg}
        if self.field_norm_ut is not None:
            out["field_norm_ut"] = self.field_norm_ut
        return out


@dataclass(frozen=True)
class StepRecord:
    """What the rig did during one step (a row of ``session.json`` ``steps``).

    ``mount`` (3, 3) body->table-top; ``table_angle`` rad at ``t_start``; ``table_rate`` rad/s
    commanded (0 when static); ``temperature_c`` the chamber setpoint (None if no chamber);
    ``extra`` holds any further keys (e.g. ``label``, ``revolutions``, ``index_angle``).
    """

    index: int
    kind: str
    t_start: float
    t_end: float
    mount: np.ndarray = field(default_factory=lambda: np.eye(3))
    table_angle: float = 0.0
    table_rate: float = 0.0
    temperature_c: float | None = None
    label: str = ""
    extra: Mapping[str, object] = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Step duration, s."""
        return self.t_end - self.t_start

    def to_dict(self) -> dict:
        out = {"index": self.index, "kind": self.kind, "t_start": self.t_start, "t_end": self.t_end,
               "mount": np.asarray(self.mount).tolist(), "table_angle": self.table_angle,
               "table_rate": self.table_rate, "temperature_c": self.temperature_c, "label": self.label}
        out.update(self.extra)
        return out

    @classmethod
    def from_dict(cls, d: Mapping, source: str = "session.json") -> StepRecord:
        known = {"index", "kind", "t_start", "t_end", "mount", "table_angle", "table_rate", "temperature_c", "label"}
        try:
            idx = int(d["index"])
        except (KeyError, TypeError, ValueError):
            raise SessionError(f"{source}: a step has no integer 'index'") from None
        where = f"{source}: step {idx}"
        for key in ("kind", "t_start", "t_end"):
            if key not in d:
                raise SessionError(f"{where}: missing field {key!r}")
        if d["kind"] not in STEP_KINDS:
            raise SessionError(f"{where}: unknown kind {d['kind']!r} (expected one of {', '.join(STEP_KINDS)})")
        try:
            mount = np.array(d.get("mount", np.eye(3)), float)
        except (TypeError, ValueError):
            mount = np.full(1, np.nan)
        if mount.shape != (3, 3) or not np.all(np.isfinite(mount)):
            raise SessionError(f"{where}: 'mount' must be a finite 3x3 matrix")
        if not np.allclose(mount @ mount.T, np.eye(3), atol=1e-6) or np.linalg.det(mount) < 0:
            raise SessionError(f"{where}: 'mount' is not a rotation matrix")
        t0, t1 = finite(d["t_start"], f"{where}: t_start"), finite(d["t_end"], f"{where}: t_end")
        if not t1 > t0:
            raise SessionError(f"{where}: t_end {t1} is not after t_start {t0}")
        temp = d.get("temperature_c")
        return cls(idx, d["kind"], t0, t1, mount, finite(d.get("table_angle") or 0.0, f"{where}: table_angle"),
                   finite(d.get("table_rate") or 0.0, f"{where}: table_rate"),
                   None if temp is None else finite(temp, f"{where}: temperature_c"),
                   str(d.get("label", "")), {k: v for k, v in d.items() if k not in known})


def finite(value: object, where: str) -> float:
    """``value`` as a finite float (a bool is not a number), else a SessionError naming ``where``."""
    try:
        x = float(value) if not isinstance(value, (bool, str)) else float("nan")
    except (TypeError, ValueError):
        x = float("nan")
    if not np.isfinite(x):
        raise SessionError(f"{where}: expected a finite number, got {value!r}")
    return x
