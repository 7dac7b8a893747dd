"""AXD-LNS dead reckoning on a drive: what the calibration set buys on the road (validation).

The thesis' land navigator (shared/seeds/000_... ch. 2; :mod:`workbench.nav.lns`): odometer
speed through the z-gyro heading and the accelerometer pitch, GPS-aided by an EKF of eq. 2.20
(5 states, with the odometer scale factor) or its 4-state variant (without), closed loop
(eq. 2.27). The GPS is used until ``gps_loss_s`` (the thesis' "SW command") and, as in the thesis,
kept as the reference from then on: the position error is reported in % of the distance
travelled since the loss (the GPS track length), with the statistics of tables 2.3-2.9
(max, mean, std, RMS, "1σ" = mean + std), leaving out the first ``skip_distance_m``.

Runs, each with both variants: ``raw`` (uncompensated samples), ``calibrated`` (samples
compensated with the set) and ``wrong_bias`` (the set with its z-gyro bias shifted by
``wrong_gyro_bias_deg_h``); the process noise comes from the set's noise block in all runs.
The at-rest initialisation (sec. 2.3.2) measures the z-gyro bias again (``bias_at_rest``), which
hides a wrong set bias; the ``wrong_bias`` run is therefore made without it, so it shows what
the set's bias alone does.

Recording (``workbench run lns-dead-reckoning --rig sim``): the simulated vehicle
(:mod:`workbench.sim.vehicle`) drives ``road`` (default: the thesis-like drive of
:func:`workbench.sim.roads.thesis_drive`, ~105 minutes, odometer +4 % after the stop at 3000 s,
GPS lost at 3600 s, 28-30 km in 45 minutes without GPS). ``initial_heading_error_deg``: the
filter starts from the true heading plus this error instead of waiting for the course over
ground (thesis Fig. 2.14: 180°).

``result.json``: per run (``raw``, ``calibrated``, ``wrong_bias``) a block per variant
(``sf_state``, ``no_sf_state``) with ``error_pct`` (max, mean, std, rms, one_sigma),
``distance_m``, ``final_error_m``, ``odo_scale_final`` and its sigma, ``sf_settle_s`` (time after the
restart for the scale-factor estimate to come within 0.5 % of its value at the GPS loss),
``gyro_bias_final`` rad/s, ``heading_resets_s``, ``heading_known_s``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from workbench.calset import CalibrationSet
from workbench.earth import radii
from workbench.errors import AnalysisError
from workbench.nav.compensate import check_calibration, compensate, imu_samples, process_noise
from workbench.nav.lns import LnsConfig, error_statistics, run_lns, track_length
from workbench.nav.road import gps_fixes, odometer_distance, thin
from workbench.options import Option, check_options, defaults
from workbench.procedure import ProcedureResult
from workbench.session import Session

NAME = "lns-dead-reckoning"
TITLE = "AXD-LNS odometer dead reckoning with GPS loss, raw vs calibrated (validation, thesis ch. 2)"
TRIADS = ("accel", "gyro")
CAMPAIGN_ORDER = None  # a validation run, not a calibration step
DRIVE = True  # recorded on the simulated vehicle, not on the turntable
OPTIONS = (
    Option("road", "sequence", "list", None, "road legs ({kind: straight|turn|stop, ...}); default the thesis-like drive"),
    Option("road_seed", "sequence", "int", 1, "seed of the thesis-like road", ge=0),
    Option("heading0_deg", "sequence", "float", 270.0, "start heading of the vehicle", unit="deg"),
    Option("latitude_deg", "sequence", "float", 40.9, "start latitude", unit="deg", ge=-89.0, le=89.0),
    Option("longitude_deg", "sequence", "float", 14.2, "start longitude", unit="deg"),
    Option("height_m", "sequence", "float", 50.0, "start height (WGS-84)", unit="m"),
    Option("gps_loss_s", "analysis", "float", 3600.0, "GPS ignored from this time (the thesis' SW command)",
           unit="s", gt=0),
    Option("skip_distance_m", "analysis", "float", 1000.0, "distance after the loss left out of the % statistics",
           unit="m", ge=0),
    Option("gps_sigma_m", "analysis", "float", 3.0, "1-sigma of a GPS fix per horizontal axis", unit="m", gt=0),
    Option("filter_step_s", "analysis", "float", 1.0, "EKF step", unit="s", gt=0),
    Option("sf_random_walk_pct_per_sqrt_s", "analysis", "float", 0.2, "odometer scale-factor random walk",
           unit="%/√s", ge=0),
    Option("initial_heading_error_deg", "analysis", "float", None,
           "start from the true heading plus this error (thesis Fig. 2.14); unset = course over ground",
           unit="deg"),
    Option("bias_at_rest", "analysis", "bool", True, "measure the z-gyro bias at rest (thesis sec. 2.3.2)"),
    Option("wrong_gyro_bias_deg_h", "analysis", "float", 20.0, "z-gyro bias error of the wrong-bias run",
           unit="deg/h"),
    Option("force", "analysis", "bool", False, "accept a set of another serial"),
)
DEFAULTS = defaults(OPTIONS)


def _road(o: dict) -> tuple[list[dict], dict, dict]:
    """(road legs, odometer, gps) of the checked sequence options ``o``: the ``road`` option, else the thesis drive."""
    from workbench.sim.roads import thesis_drive

    return thesis_drive(int(o["road_seed"])) if o["road"] is None else (o["road"], {}, {})


def legs(**options) -> list[dict]:
    """The road legs (lab units) the simulated vehicle drives for the sequence ``options``."""
    return _road(check_options(NAME, OPTIONS, options, "sequence"))[0]


def record_drive(truth, seed: int, out_dir, **options) -> Session:
    """Simulate the drive of ``options`` with the unit ``truth`` into ``out_dir``; returns the session."""
    from workbench.session import Site, load_session
    from workbench.sim.vehicle import drive, drive_config

    o = check_options(NAME, OPTIONS, options, "sequence")
    road, odo, gps = _road(o)
    cfg = drive_config(road, Site(float(o["latitude_deg"]), float(o["longitude_deg"]), float(o["height_m"])),
                       float(o["heading0_deg"]), odometer=odo, gps=gps)
    drive(cfg, truth, seed, out_dir, procedure=NAME)
    return load_session(out_dir)


def sequence(spec, **options):
    """The drive as a one-line description (the vehicle, not the turntable, records it)."""
    from workbench.errors import ProcedureError

    raise ProcedureError(f"{NAME}: recorded on the simulated vehicle (workbench run {NAME} --rig sim), "
                         "or analysed from a drive session (workbench analyze)")


def _wrong_bias(cal: CalibrationSet, shift: float) -> CalibrationSet:
    """The set with its z-gyro bias shifted by ``shift`` rad/s."""
    triads = dict(cal.triads)
    g = triads["gyro"]
    model = replace(g.model, bias=np.asarray(g.model.bias) + np.array([0.0, 0.0, shift]))
    triads["gyro"] = replace(g, model=model)
    return replace(cal, triads=triads)


def _errors_vs_gps(res, gps, t_loss: float, skip_m: float) -> tuple[dict, dict]:
    """Statistics of the filter's horizontal error against the GPS fixes after the loss."""
    sel = gps["t"].to_numpy() >= t_loss
    g = gps[sel]
    if len(g) < 2:
        raise AnalysisError(f"no GPS fixes after gps_loss_s={t_loss:g} s to compare with")
    gt = g["t"].to_numpy()
    lat = np.interp(gt, res.t, res.lat)
    lon = np.interp(gt, res.t, res.lon)
    rm, rn = radii(lat)
    dn = (lat - g["lat"].to_numpy()) * rm
    de = (lon - g["lon"].to_numpy()) * rn * np.cos(lat)
    err = np.hypot(dn, de)
    dist = track_length(g["lat"].to_numpy(), g["lon"].to_numpy())
    return error_statistics(err, dist, skip_m), {"t": gt, "error_m": err, "distance_m": dist}


def _sf_settle(res, t_loss: float) -> float | None:
    """Seconds after the last stop before the loss until the SF estimate stays within 0.5 % of its value at the loss."""
    if not np.any(np.isfinite(res.odo_scale)):
        return None
    k_loss = int(np.searchsorted(res.t, t_loss))
    stopped = np.nonzero((res.speed[:k_loss] < 0.1))[0]
    if len(stopped) == 0:
        return None
    k0 = int(stopped[-1])
    target = res.odo_scale[k_loss - 1]
    off = np.nonzero(np.abs(res.odo_scale[k0:k_loss] - target) > 0.005)[0]
    k = k0 + (int(off[-1]) + 1 if len(off) else 0)
    return float(res.t[min(k, k_loss - 1)] - res.t[k0])


def analyze(session: Session, calibration: CalibrationSet | None = None, **options) -> ProcedureResult:
    """Raw, calibrated and wrong-bias LNS runs with and without the SF state (module docstring)."""
    o = check_options(NAME, OPTIONS, options, "analysis")
    warnings = check_calibration(calibration, session.unit.serial, ("gyro", "accel"), bool(o["force"]), NAME)
    if not session.steps_of_kind("drive"):
        raise AnalysisError(f"{session.name}: no drive step (a session of the simulated vehicle or an imported drive)")
    gps = gps_fixes(session)
    if gps is None:
        raise AnalysisError(f"{session.name}: no gps.parquet / gps.csv (the filter needs GPS until the loss)")
    odo = odometer_distance(session)
    raw = imu_samples(session.samples, session.sample_rate_hz, session.name)
    noise = process_noise(calibration, fallback=raw)
    warnings += list(noise.notes)
    t_loss = float(o["gps_loss_s"])
    if not gps["t"].iloc[0] < t_loss < session.samples["t"].iloc[-1]:
        raise AnalysisError(f"{session.name}: gps_loss_s={t_loss:g} s is not inside the drive")
    heading0 = None
    if o["initial_heading_error_deg"] is not None:
        drive_opts = session.options.get("drive") or {}
        if "heading0" not in drive_opts:
            raise AnalysisError(f"{session.name}: initial_heading_error_deg needs the session's true start heading "
                                "(options.drive.heading0, written by the simulator)")
        heading0 = float(drive_opts["heading0"]) + float(np.radians(o["initial_heading_error_deg"]))
    base = LnsConfig(step_s=float(o["filter_step_s"]), gps_sigma=float(o["gps_sigma_m"]), gps_loss_s=t_loss,
                     initial_heading=heading0, sf_random_walk=float(o["sf_random_walk_pct_per_sqrt_s"]) / 100,
                     bias_at_rest=bool(o["bias_at_rest"]))
    shift = o.si("wrong_gyro_bias_deg_h")
    inputs = {"raw": (raw, base),
              "calibrated": (compensate(raw, calibration, ("gyro", "accel")), base),
              "wrong_bias": (compensate(raw, _wrong_bias(calibration, shift), ("gyro", "accel")),
                             replace(base, bias_at_rest=False))}
    blocks, payload = {}, {"runs": {}, "t_loss": t_loss, "gps": gps[["t", "lat", "lon"]].to_dict("list")}
    for mode, (samples, cfg) in inputs.items():
        blocks[mode] = {}
        for variant, sf in (("sf_state", True), ("no_sf_state", False)):
            res = run_lns(samples, odo, gps, session.site.latitude, noise, replace(cfg, sf_state=sf))
            stats, series = _errors_vs_gps(res, gps, t_loss, float(o["skip_distance_m"]))
            k_loss = int(np.searchsorted(res.t, t_loss)) - 1
            blocks[mode][variant] = {
                "error_pct": {k: stats[k] for k in ("max", "mean", "std", "rms", "one_sigma")},
                "distance_m": stats["distance_m"], "final_error_m": stats["final_error_m"],
                "odo_scale_at_loss": None if not sf else float(res.odo_scale[k_loss]),
                "odo_scale_sigma_at_loss": None if not sf else float(res.sigma[k_loss, 2]),
                "sf_settle_s": _sf_settle(res, t_loss) if sf else None,
                "gyro_bias_final": float(res.gyro_bias[-1]), "gyro_bias_sigma_final": float(res.sigma[-1, 4]),
                "heading_resets_s": res.resets, "heading_known_s": res.t_heading,
            }
            warnings += [f"{mode}/{variant}: {n}" for n in res.notes]
            payload["runs"][f"{mode}/{variant}"] = {"t": res.t[::10], "lat": res.lat[::10], "lon": res.lon[::10],
                                                    "odo_scale": res.odo_scale, "t_all": res.t,
                                                    "heading": res.heading, **{k: v for k, v in series.items()}}
    result = {**blocks, "series": _series(payload), "gps_loss_s": t_loss, "skip_distance_m": float(o["skip_distance_m"]),
              "calibration_id": calibration.id, "wrong_gyro_bias_deg_h": float(o["wrong_gyro_bias_deg_h"]),
              "seed_tables": {"table_2_8_no_sf_state_pct": {"max": 5.5, "mean": 4.0, "std": 0.9, "rms": 4.2,
                                                            "one_sigma": 4.9},
                              "table_2_9_sf_state_pct": {"max": 1.3, "mean": 0.6, "std": 0.3, "rms": 0.7,
                                                         "one_sigma": 0.9},
                              "fig_2_18_sf_estimate": 0.035}}
    return ProcedureResult(NAME, result, None, payload, _summary(blocks), warnings)


def _series(payload: dict) -> dict:
    """Thinned series stored in result.json: error % vs distance per run, SF estimate vs time,
    the calibrated 5-state track and the GPS track (lat, lon in degrees)."""
    out = {"error_pct": {}, "odo_scale": {}}
    for name, r in payload["runs"].items():
        d = np.asarray(r["distance_m"])
        with np.errstate(divide="ignore", invalid="ignore"):
            pct = np.where(d > 0, 100 * np.asarray(r["error_m"]) / d, np.nan)
        out["error_pct"][name] = {"distance_m": thin(d), "pct": thin(pct)}
        if name.endswith("/sf_state"):
            out["odo_scale"][name] = {"t": thin(r["t_all"]), "value": thin(r["odo_scale"])}
    track = payload["runs"]["calibrated/sf_state"]
    out["track"] = {"lat_deg": thin(np.degrees(track["lat"]), 500), "lon_deg": thin(np.degrees(track["lon"]), 500)}
    gps = payload["gps"]
    out["gps"] = {"lat_deg": thin(np.degrees(gps["lat"]), 500), "lon_deg": thin(np.degrees(gps["lon"]), 500)}
    return out


def _summary(blocks: dict) -> list[str]:
    lines = []
    for mode, b in blocks.items():
        for variant, r in b.items():
            e = r["error_pct"]
            sf = "" if r["odo_scale_at_loss"] is None else f", odometer SF {100 * r['odo_scale_at_loss']:+.2f} %"
            lines.append(f"{mode} {variant}: error max {e['max']:.2f} % / mean {e['mean']:.2f} % of "
                         f"{r['distance_m'] / 1000:.1f} km without GPS (final {r['final_error_m']:.0f} m){sf}")
    return lines


def figures(result: ProcedureResult) -> dict:
    """Trajectory, error in % of distance (thesis Fig. 2.17/2.20) and the SF estimate (Fig. 2.18)."""
    from workbench.plots.lns import lns_figures

    return lns_figures(result.payload) if result.payload else {}
