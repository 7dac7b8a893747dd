"""Rig configuration files (``fixtures/rigs/*.yaml``): driver, site, limits.

Shared by the simulated rig and the real-rig drivers, so every procedure is checked against
the same limits before anything moves. YAML holds lab units with labelled keys
(``max_rate_dps``, ``max_ramp_c_per_min``); :class:`RigConfig` holds SI.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from workbench.errors import RigLimitError, WorkbenchError
from workbench.session import Site

REPO = Path(__file__).resolve().parents[1]
RIGS_DIR = REPO / "fixtures" / "rigs"


@dataclass(frozen=True)
class TurntableLimits:
    """Single-axis level turntable: limits in SI (rad/s, rad/s^2, rad, s)."""

    max_rate: float = np.radians(1000.0)
    max_accel: float = np.radians(500.0)
    positioning_error: float = np.radians(0.01)  # 1-sigma fixture/positioning error per step
    settle_s: float = 2.0
    encoder_resolution: float = np.radians(1e-4)


@dataclass(frozen=True)
class ChamberLimits:
    """Climatic chamber: air temperature range and ramp-rate limit."""

    min_c: float = -55.0
    max_c: float = 125.0
    max_ramp_c_per_min: float = 5.0
    initial_c: float = 23.0
    safe_c: float = 23.0


@dataclass(frozen=True)
class RigConfig:
    """A rig: driver name, site, magnetic field (µT, NED), turntable and chamber limits, driver options."""

    name: str
    driver: str
    site: Site
    magnetic_field_ned: np.ndarray
    turntable: TurntableLimits
    chamber: ChamberLimits
    options: Mapping = field(default_factory=dict)
    path: Path | None = None


def magnetic_field_ned(intensity_ut: float, dip_deg: float, declination_deg: float) -> np.ndarray:
    """Field vector (3,) µT in NED from intensity, dip (inclination, down positive) and declination."""
    dip, dec = np.radians(dip_deg), np.radians(declination_deg)
    return intensity_ut * np.array([np.cos(dip) * np.cos(dec), np.cos(dip) * np.sin(dec), np.sin(dip)])


def _get(d: Mapping, key: str, default, source: str, kind=float):
    value = d.get(key, default)
    try:
        return None if value is None else kind(value)
    except (TypeError, ValueError):
        raise WorkbenchError(f"{source}: field {key!r}: expected a number, got {value!r}") from None


def rig_config_from_dict(d: Mapping, source: str = "<rig>") -> RigConfig:
    """Parse a rig configuration dict (lab units, labelled keys) into SI."""
    if not isinstance(d, Mapping):
        raise WorkbenchError(f"{source}: a rig configuration must be a YAML mapping")
    for key in ("driver", "site"):
        if key not in d:
            raise WorkbenchError(f"{source}: missing field {key!r}")
    s = d["site"]
    if not isinstance(s, Mapping) or s.get("latitude_deg") is None:
        raise WorkbenchError(f"{source}: missing field 'site.latitude_deg'")
    mf = d.get("magnetic_field", {}) or {}
    site = Site(_get(s, "latitude_deg", None, source), _get(s, "longitude_deg", 0.0, source),
                _get(s, "height_m", 0.0, source), _get(s, "table_zero_azimuth_deg", None, source),
                _get(mf, "intensity_ut", None, source))  # the lab's reference field, when it measured one
    field_ned = magnetic_field_ned(_get(mf, "intensity_ut", 48.0, source), _get(mf, "dip_deg", 60.0, source),
                                   _get(mf, "declination_deg", 0.0, source))
    tt, ch = d.get("turntable", {}) or {}, d.get("chamber", {}) or {}
    d0, c0 = TurntableLimits(), ChamberLimits()
    turntable = TurntableLimits(
        max_rate=np.radians(_get(tt, "max_rate_dps", np.degrees(d0.max_rate), source)),
        max_accel=np.radians(_get(tt, "max_accel_dps2", np.degrees(d0.max_accel), source)),
        positioning_error=np.radians(_get(tt, "positioning_error_deg", np.degrees(d0.positioning_error), source)),
        settle_s=_get(tt, "settle_s", d0.settle_s, source),
        encoder_resolution=np.radians(_get(tt, "encoder_resolution_deg", np.degrees(d0.encoder_resolution), source)),
    )
    chamber = ChamberLimits(
        min_c=_get(ch, "min_c", c0.min_c, source), max_c=_get(ch, "max_c", c0.max_c, source),
        max_ramp_c_per_min=_get(ch, "max_ramp_c_per_min", c0.max_ramp_c_per_min, source),
        initial_c=_get(ch, "initial_c", c0.initial_c, source), safe_c=_get(ch, "safe_c", c0.safe_c, source),
    )
    known = {"name", "driver", "site", "magnetic_field", "turntable", "chamber"}
    return RigConfig(str(d.get("name", d["driver"])), str(d["driver"]), site, field_ned, turntable, chamber,
                     {k: v for k, v in d.items() if k not in known})


def load_rig_config(name_or_path: str | Path) -> RigConfig:
    """Load ``fixtures/rigs/<name>.yaml`` or a YAML path; ``"sim"`` is the default simulated rig."""
    p = Path(name_or_path)
    if not p.suffix:
        p = RIGS_DIR / f"{name_or_path}.yaml"
    if not p.exists():
        known = ", ".join(sorted(x.stem for x in RIGS_DIR.glob("*.yaml")))
        raise WorkbenchError(f"{name_or_path}: no such rig configuration (known: {known})")
    try:
        data = yaml.safe_load(p.read_text())
    except yaml.YAMLError as exc:
        raise WorkbenchError(f"{p}: not valid YAML ({str(exc).splitlines()[0]})") from None
    cfg = rig_config_from_dict(data, str(p))
    return RigConfig(**{**cfg.__dict__, "path": p})


def check_plan(plan, cfg: RigConfig) -> None:
    """Refuse a plan outside the rig's limits, naming the step; called before anything runs."""
    tt, ch = cfg.turntable, cfg.chamber
    for i, p in enumerate(plan):
        where = f"rig {cfg.name}: step {i} ({p.kind}{', ' + p.label if p.label else ''})"
        if abs(p.table_rate) > tt.max_rate * (1 + 1e-9):
            raise RigLimitError(f"{where}: table rate {np.degrees(p.table_rate):.1f} °/s exceeds the limit "
                                f"{np.degrees(tt.max_rate):.1f} °/s")
        if p.temperature_c is not None and not ch.min_c <= p.temperature_c <= ch.max_c:
            raise RigLimitError(f"{where}: chamber setpoint {p.temperature_c:.1f} °C outside "
                                f"{ch.min_c:.0f}..{ch.max_c:.0f} °C")
        ramp = p.extra.get("ramp_rate_c_per_min")
        if ramp is not None:
            if abs(ramp) > ch.max_ramp_c_per_min * (1 + 1e-9):
                raise RigLimitError(f"{where}: ramp {abs(ramp):.2f} °C/min exceeds the chamber limit "
                                    f"{ch.max_ramp_c_per_min:.2f} °C/min")
            if not ch.min_c <= p.extra["ramp_to_c"] <= ch.max_c:
                raise RigLimitError(f"{where}: ramp target {p.extra['ramp_to_c']:.1f} °C outside "
                                    f"{ch.min_c:.0f}..{ch.max_c:.0f} °C")
