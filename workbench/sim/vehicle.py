"""The virtual vehicle: a road trajectory through the virtual IMU, an odometer and a GPS receiver.

:func:`drive` turns a :class:`DriveConfig` (road legs, start point, sensors) into a session in
the workbench format (``docs/formats.md``: one ``drive`` step per road leg), with

* ``samples``: the IMU (``workbench.sim.sensor.VirtualIMU``: the unit's error model, noise and
  seed exactly as on the turntable rig), the unit's thermometer and the odometer's cumulative
  distance ``odo_distance`` (m): true distance of the reference point times ``1 + scale factor``
  (the scale factor may step at given times, e.g. a tyre deflating), plus wheel slip
  (extra wheel travel over given intervals), white speed noise, quantised to whole pulses;
* ``gps.parquet``: fixes at ``gps_rate_hz`` of the antenna (lever arm from the reference
  point): ``t`` s, ``lat``, ``lon`` rad, ``h`` m, ``vn``, ``ve``, ``vd`` m/s with white noise, none
  inside the outages;
* ``trajectory.parquet`` (the truth, read by tests and benchmarks, never by analyses): IMU
  point ``lat``, ``lon``, ``h``, ``vn``, ``ve``, ``vd``, ``roll``, ``pitch``, ``yaw`` (body), reference
  point ``ref_lat``, ``ref_lon``, ``ref_h``, ``speed``, ``distance``, ``heading``, ``odo_scale``;
  and ``truth.json`` (the unit's true model, the drive configuration, the seed).

Seeds: the unit's noise is ``VirtualIMU(truth, seed)`` as on the turntable rig; the odometer
and GPS draw from ``SeedSequence([seed, 11])`` and ``[seed, 12]``.

Public: :class:`Odometer`, :class:`Gps`, :class:`DriveConfig`, :func:`drive_config`,
:func:`drive`, :func:`load_truth_trajectory` (the GPS file is read by analyses with
:func:`workbench.nav.road.gps_fixes`).
"""

from __future__ import annotations

import json
import uuid
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd

from workbench.calset import Unit, atomic_write_text
from workbench.errors import WorkbenchError
from workbench.session import Session, Site, StepRecord, write_session
from workbench.earth import radii
from workbench.sim.trajectory import Leg, Limits, Trajectory, generate, leg_from_dict

GPS_FILE = "gps.parquet"  # the name workbench.nav.road.gps_fixes reads (docs/formats.md)

TRUTH_FILE = "trajectory.parquet"


@dataclass(frozen=True)
class Odometer:
    """Odometer model: ``scale_factor`` (fraction, e.g. 0.01 = +1 %), ``scale_steps`` list of
    ``[t_s, new scale factor]``, ``pulse_m`` distance per pulse (quantisation), ``speed_noise``
    m/s/√Hz white noise on the wheel speed, ``slip`` list of ``[t0_s, t1_s, fraction]``
    (the wheel turns by ``1 + fraction`` times the true distance inside the interval)."""

    scale_factor: float = 0.0
    scale_steps: tuple = ()
    pulse_m: float = 0.01
    speed_noise: float = 0.005
    slip: tuple = ()


@dataclass(frozen=True)
class Gps:
    """GPS model: ``rate_hz``; white noise ``sigma_h`` m (north, east), ``sigma_v`` m (down),
    ``sigma_vel`` m/s; ``outages`` list of ``[t0_s, t1_s]`` without fixes (t1 may be infinite);
    ``lever_arm`` (3,) m antenna from the reference point, vehicle frame."""

    rate_hz: float = 1.0
    sigma_h: float = 2.0
    sigma_v: float = 4.0
    sigma_vel: float = 0.1
    outages: tuple = ()
    lever_arm: tuple = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class DriveConfig:
    """A drive: road ``legs``, start ``site`` and ``heading0`` rad, ``limits``, IMU ``lever_arm``
    (3,) m and ``boresight`` (roll, pitch, yaw) rad, ``odometer``, ``gps``, ``temperature_c``."""

    legs: tuple[Leg, ...]
    site: Site
    heading0: float = 0.0
    limits: Limits = field(default_factory=Limits)
    lever_arm: tuple = (0.0, 0.0, 0.0)
    boresight: tuple = (0.0, 0.0, 0.0)
    odometer: Odometer = field(default_factory=Odometer)
    gps: Gps = field(default_factory=Gps)
    temperature_c: float = 25.0


def drive_config(road: list[Mapping], site: Site, heading0_deg: float = 0.0, odometer: Mapping | None = None,
                 gps: Mapping | None = None, lever_arm_m=(0.0, 0.0, 0.0), boresight_deg=(0.0, 0.0, 0.0),
                 temperature_c: float = 25.0) -> DriveConfig:
    """A :class:`DriveConfig` from lab-unit descriptions.

    ``road``: legs as :func:`workbench.sim.trajectory.leg_from_dict`; ``odometer``: keys
    ``scale_factor_pct``, ``scale_steps`` (``[[t_s, pct], ...]``), ``pulse_m``,
    ``speed_noise_mps_per_sqrt_hz``, ``slip`` (``[[t0_s, t1_s, pct], ...]``); ``gps``: keys
    ``rate_hz``, ``sigma_h_m``, ``sigma_v_m``, ``sigma_vel_mps``, ``outages`` (``[[t0_s, t1_s], ...]``,
    ``null`` = to the end), ``lever_arm_m``.
    """
    legs = tuple(leg_from_dict(d, f"road leg {i}") for i, d in enumerate(road))
    o = dict(odometer or {})
    g = dict(gps or {})
    known_o = {"scale_factor_pct", "scale_steps", "pulse_m", "speed_noise_mps_per_sqrt_hz", "slip"}
    known_g = {"rate_hz", "sigma_h_m", "sigma_v_m", "sigma_vel_mps", "outages", "lever_arm_m"}
    for name, d, known in (("odometer", o, known_o), ("gps", g, known_g)):
        bad = set(d) - known
        if bad:
            raise WorkbenchError(f"drive {name}: unknown field(s) {', '.join(sorted(bad))} (known: {', '.join(sorted(known))})")
    odo = Odometer(scale_factor=float(o.get("scale_factor_pct", 0.0)) / 100,
                   scale_steps=tuple((float(t), float(p) / 100) for t, p in o.get("scale_steps", ())),
                   pulse_m=float(o.get("pulse_m", 0.01)),
                   speed_noise=float(o.get("speed_noise_mps_per_sqrt_hz", 0.005)),
                   slip=tuple((float(a), float(b), float(p) / 100) for a, b, p in o.get("slip", ())))
    gp = Gps(rate_hz=float(g.get("rate_hz", 1.0)), sigma_h=float(g.get("sigma_h_m", 2.0)),
             sigma_v=float(g.get("sigma_v_m", 4.0)), sigma_vel=float(g.get("sigma_vel_mps", 0.1)),
             outages=tuple((float(a), np.inf if b is None else float(b)) for a, b in g.get("outages", ())),
             lever_arm=tuple(float(x) for x in g.get("lever_arm_m", (0.0, 0.0, 0.0))))
    if odo.pulse_m <= 0 or gp.rate_hz <= 0:
        raise WorkbenchError("drive: odometer pulse_m and gps rate_hz must be > 0")
    return DriveConfig(legs, site, float(np.radians(heading0_deg)), Limits(), tuple(map(float, lever_arm_m)),
                       tuple(float(np.radians(b)) for b in boresight_deg), odo, gp, float(temperature_c))


def _odometer(tr: Trajectory, odo: Odometer, dt: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Cumulative odometer distance (N,) m and the true scale factor in force (N,)."""
    sf = np.full(len(tr.t), odo.scale_factor)
    for t0, value in sorted(odo.scale_steps):
        sf[tr.t >= t0] = value
    slip = np.zeros(len(tr.t))
    for t0, t1, frac in odo.slip:
        slip[(tr.t >= t0) & (tr.t < t1)] += frac
    inc = np.diff(tr.distance, prepend=0.0) * (1.0 + sf + slip)
    moving = tr.speed > 0.0
    inc += np.where(moving, odo.speed_noise * np.sqrt(dt) * rng.standard_normal(len(inc)), 0.0)
    dist = np.cumsum(inc)
    return np.floor(dist / odo.pulse_m) * odo.pulse_m, sf


def _gps(tr: Trajectory, cfg: DriveConfig, rng: np.random.Generator) -> pd.DataFrame:
    """GPS fixes of the antenna (white noise, outages removed)."""
    fs = 1.0 / (tr.t[1] - tr.t[0])
    step = max(1, int(round(fs / cfg.gps.rate_hz)))
    k = np.arange(0, len(tr.t), step)
    keep = np.ones(len(k), bool)
    for t0, t1 in cfg.gps.outages:
        keep &= ~((tr.t[k] >= t0) & (tr.t[k] < t1))
    k = k[keep]
    lever = np.asarray(cfg.gps.lever_arm)
    c_vn = np.stack([np.cos(tr.heading[k]) * np.cos(tr.pitch[k]), np.sin(tr.heading[k]) * np.cos(tr.pitch[k]),
                     -np.sin(tr.pitch[k])], axis=1)
    right = np.stack([-np.sin(tr.heading[k]), np.cos(tr.heading[k]), np.zeros(len(k))], axis=1)
    down = np.cross(c_vn, right)
    dp = lever[0] * c_vn + lever[1] * right + lever[2] * down  # NED offset of the antenna
    rm, rn = radii(tr.ref_lat[k])
    g = cfg.gps
    noise = rng.standard_normal((len(k), 6))
    dn, de, dd = dp[:, 0] + g.sigma_h * noise[:, 0], dp[:, 1] + g.sigma_h * noise[:, 1], dp[:, 2] + g.sigma_v * noise[:, 2]
    v = tr.ref_v_ned[k] + g.sigma_vel * noise[:, 3:]
    return pd.DataFrame({"t": tr.t[k], "lat": tr.ref_lat[k] + dn / (rm + tr.ref_h[k]),
                         "lon": tr.ref_lon[k] + de / ((rn + tr.ref_h[k]) * np.cos(tr.ref_lat[k])),
                         "h": tr.ref_h[k] - dd, "vn": v[:, 0], "ve": v[:, 1], "vd": v[:, 2]})


def _truth_frame(tr: Trajectory, odo_sf: np.ndarray) -> pd.DataFrame:
    from scipy.spatial.transform import Rotation

    ypr = Rotation.from_matrix(tr.c_bn).as_euler("ZYX")
    return pd.DataFrame({"t": tr.t, "lat": tr.lat, "lon": tr.lon, "h": tr.h, "vn": tr.v_ned[:, 0],
                         "ve": tr.v_ned[:, 1], "vd": tr.v_ned[:, 2], "roll": ypr[:, 2], "pitch": ypr[:, 1],
                         "yaw": ypr[:, 0], "ref_lat": tr.ref_lat, "ref_lon": tr.ref_lon, "ref_h": tr.ref_h,
                         "speed": tr.speed, "distance": tr.distance, "heading": tr.heading, "odo_scale": odo_sf})


def drive(cfg: DriveConfig, unit, seed: int, out_dir: str | Path | None = None,
          procedure: str = "drive") -> tuple[Session, dict]:
    """Simulate the drive ``cfg`` with ``unit`` (a ``UnitTruth``); returns the session and its truth.

    The truth dict holds ``trajectory`` (DataFrame, as ``trajectory.parquet``), ``gps``
    (DataFrame), ``unit`` (the UnitTruth), ``trajectory_object`` (:class:`Trajectory`).
    With ``out_dir`` the session is written there (all files first to a temporary folder
    beside it, then renamed: a failed run leaves nothing half-written).
    """
    from workbench.sim.sensor import VirtualIMU

    fs = float(unit.sample_rate_hz)
    site = cfg.site
    tr = generate(cfg.legs, fs, site.latitude, float(np.radians(site.longitude_deg)), site.height_m, cfg.heading0,
                  cfg.limits, cfg.lever_arm, cfg.boresight)
    imu = VirtualIMU(unit, seed)
    temp = np.full(len(tr.t), cfg.temperature_c)
    out = imu.measure(tr.omega_ib_b, tr.f_b, None if "mag" not in unit.triads else np.zeros((len(tr.t), 3)), temp)
    odo_rng, gps_rng = (np.random.default_rng(s) for s in (np.random.SeedSequence([seed, 11]),
                                                          np.random.SeedSequence([seed, 12])))
    odo, sf = _odometer(tr, cfg.odometer, 1.0 / fs, odo_rng)
    data = {"t": tr.t, "step": tr.leg.astype(np.int64)}
    data.update({c: out["gyro"][:, i] for i, c in enumerate(("gx", "gy", "gz"))})
    data.update({c: out["accel"][:, i] for i, c in enumerate(("ax", "ay", "az"))})
    data["temp"] = out["temp"]
    data["odo_distance"] = odo
    steps = [StepRecord(i, "drive", float(tr.leg_starts[i]), float(tr.leg_starts[i + 1]),
                        temperature_c=cfg.temperature_c, label=leg.label or leg.kind,
                        extra={"road": leg.kind, "speed_mps": leg.speed, "yaw_rate_dps": float(np.degrees(leg.yaw_rate)),
                               "slope_deg": float(np.degrees(leg.slope))})
             for i, leg in enumerate(cfg.legs)]
    session = Session(id=str(uuid.uuid4()), unit=Unit(unit.serial, unit.model), site=site, sample_rate_hz=fs,
                      procedure=procedure, steps=steps, samples=pd.DataFrame(data), rig="vehicle-sim",
                      options={"drive": _config_json(cfg), "seed": int(seed)},
                      created=datetime.now(UTC).isoformat(timespec="seconds"))
    gps = _gps(tr, cfg, gps_rng)
    truth_df = _truth_frame(tr, sf)
    if out_dir is not None:
        _write(Path(out_dir), session, gps, truth_df, unit, cfg, seed)
    return session, {"trajectory": truth_df, "gps": gps, "unit": unit, "trajectory_object": tr}


def _config_json(cfg: DriveConfig) -> dict:
    d = asdict(cfg)
    d["site"] = cfg.site.to_dict()
    return json.loads(json.dumps(d, default=lambda o: None if isinstance(o, float) and not np.isfinite(o) else str(o)))


def _write(out_dir: Path, session: Session, gps: pd.DataFrame, truth_df: pd.DataFrame, unit, cfg, seed: int) -> None:
    """Write the session, GPS, trajectory truth and truth.json, all or nothing."""
    import shutil

    tmp = out_dir.with_name(f".{out_dir.name}.tmp")
    if tmp.exists():
        shutil.rmtree(tmp)
    try:
        write_session(session, tmp)
        gps.to_parquet(tmp / GPS_FILE, index=False)
        truth_df.to_parquet(tmp / TRUTH_FILE, index=False)
        atomic_write_text(tmp / "truth.json", json.dumps({"seed": int(seed), "unit": unit.to_dict(),
                                                          "drive": _config_json(cfg)}, indent=1,
                                                         default=lambda o: np.asarray(o).tolist()))
        if out_dir.exists():
            shutil.rmtree(out_dir)
        tmp.replace(out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    session.path = out_dir


def load_truth_trajectory(session_dir: str | Path) -> pd.DataFrame:
    """The true trajectory of a simulated drive (``trajectory.parquet``; tests and benchmarks only)."""
    return pd.read_parquet(Path(session_dir) / TRUTH_FILE)
