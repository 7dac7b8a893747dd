"""Rig configuration files (``fixtures/rigs/*.yaml``): driver, site, limits.

Shared by the simulated rig and the real-rig drivers, so every procedure is checked against
the same limits before anything moves. YAML holds lab units with labelled keys
(``max_rate_dps``, ``max_ramp_c_per_min``); :class:`RigConfig` holds SI.

The file is parsed by a strict schema (:mod:`workbench.rigschema`): an unknown key is refused
with the nearest valid name, every limit is finite and in range, and a real rig (``driver:
real``) must state its turntable and chamber limits (no permissive defaults). Public:
:class:`RigConfig`, :func:`rig_config_from_dict`, :func:`load_rig_config`, :func:`check_plan`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from workbench.errors import RigLimitError, WorkbenchError
from workbench.rigschema import RigFile, parse_rig_file
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
    reference_equipment: tuple[Mapping, ...] = ()  # name, model, serial, certificate, dates, traceability


def magnetic_field_ned(intensity_ut: float, dip_deg: float, declination_deg: float) -> np.ndarray:
    """Field vector (3,) µT in NED from intensity, dip (inclination, down positive) and declination."""
    dip, dec = np.radians(dip_deg), np.radians(declination_deg)
    return intensity_ut * np.array([np.cos(dip) * np.cos(dec), np.cos(dip) * np.sin(dec), np.sin(dip)])


def _from_schema(f: RigFile) -> RigConfig:
    s, mf, tt, ch = f.site, f.magnetic_field, f.turntable, f.chamber
    site = Site(s.latitude_deg, s.longitude_deg, s.height_m, s.table_zero_azimuth_deg,
                mf.intensity_ut)  # the lab's reference field, when it measured one
    field_ned = magnetic_field_ned(48.0 if mf.intensity_ut is None else mf.intensity_ut, mf.dip_deg,
                                   mf.declination_deg)
    turntable = TurntableLimits(np.radians(tt.max_rate_dps), np.radians(tt.max_accel_dps2),
                                np.radians(tt.positioning_error_deg), tt.settle_s,
                                np.radians(tt.encoder_resolution_deg))
    chamber = ChamberLimits(ch.min_c, ch.max_c, ch.max_ramp_c_per_min, ch.initial_c, ch.safe_c)
    return RigConfig(f.name or f.driver, f.driver, site, field_ned, turntable, chamber, f.driver_options(),
                     reference_equipment=tuple(r.model_dump() for r in f.reference_equipment))


def rig_config_from_dict(d: Mapping, source: str = "<rig>") -> RigConfig:
    """Parse a rig configuration dict (lab units, labelled keys) into SI; WorkbenchError naming the field."""
    return _from_schema(parse_rig_file(d, source))


RECORD_BYTES_PER_SAMPLE = 300  # memory of one recorded sample while a step is simulated or streamed: measured
# 283 B (peak RSS of a 2e6- minus a 2e5-sample simulated Allan hold, industrial MEMS, 14 columns)


def max_step_samples() -> float:
    """Samples one step may record: the physical memory over :data:`RECORD_BYTES_PER_SAMPLE`."""
    import os

    try:
        ram = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        ram = 1 << 36
    return ram / RECORD_BYTES_PER_SAMPLE


def load_rig_config(name_or_path: str | Path) -> RigConfig:
    """Load ``fixtures/rigs/<name>.yaml`` or a YAML path; ``"sim"`` is the default simulated rig."""
    from workbench.safe_yaml import load_yaml_file

    known = ", ".join(sorted(x.stem for x in RIGS_DIR.glob("*.yaml")))
    if not str(name_or_path).strip():  # Path('') is the current folder ('.: no such rig configuration')
        raise WorkbenchError(f"empty rig name (known: {known})")
    p = Path(name_or_path)
    if not p.suffix:
        p = RIGS_DIR / f"{name_or_path}.yaml"
    if not p.is_file():
        raise WorkbenchError(f"{name_or_path}: no such rig configuration (known: {known})")
    cfg = rig_config_from_dict(load_yaml_file(p), str(p))
    return RigConfig(**{**cfg.__dict__, "path": p})


def check_plan(plan, cfg: RigConfig, sample_rate_hz: float | None = None) -> None:
    """Refuse a plan outside the rig's limits, naming the step; called before anything runs.

    With the unit's ``sample_rate_hz`` (Hz), a step whose record could not be held in this
    machine's memory (:func:`max_step_samples`) is refused too (a dwell of 1e12 s was a
    MemoryError traceback after the session folder was made).
    """
    tt, ch = cfg.turntable, cfg.chamber
    most = max_step_samples() if sample_rate_hz is not None else None
    for i, p in enumerate(plan):
        where = f"rig {cfg.name}: step {i} ({p.kind}{', ' + p.label if p.label else ''})"
        if most is not None and not p.duration_s * sample_rate_hz <= most:  # NaN and inf fail too
            raise RigLimitError(f"{where}: {p.duration_s:.4g} s at {sample_rate_hz:g} Hz is "
                                f"{p.duration_s * sample_rate_hz:.3g} samples; a step's record holds at most "
                                f"{most:.3g} in this machine's memory (about {most / sample_rate_hz / 3600:.3g} h)")
        if not abs(p.table_rate) <= tt.max_rate * (1 + 1e-9):
            raise RigLimitError(f"{where}: table rate {np.degrees(p.table_rate):.1f} °/s exceeds the limit "
                                f"{np.degrees(tt.max_rate):.1f} °/s")
        if p.temperature_c is not None and not ch.min_c <= p.temperature_c <= ch.max_c:
            raise RigLimitError(f"{where}: chamber setpoint {p.temperature_c:.1f} °C outside "
                                f"{ch.min_c:.0f}..{ch.max_c:.0f} °C")
        ramp = p.extra.get("ramp_rate_c_per_min")
        if ramp is not None:
            if not abs(ramp) <= ch.max_ramp_c_per_min * (1 + 1e-9):
                raise RigLimitError(f"{where}: ramp {abs(ramp):.2f} °C/min exceeds the chamber limit "
                                    f"{ch.max_ramp_c_per_min:.2f} °C/min")
            if not ch.min_c <= p.extra["ramp_to_c"] <= ch.max_c:
                raise RigLimitError(f"{where}: ramp target {p.extra['ramp_to_c']:.1f} °C outside "
                                    f"{ch.min_c:.0f}..{ch.max_c:.0f} °C")
