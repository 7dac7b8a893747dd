"""Paper 001's land INS on a drive: NHC, ZUPT and ZARUPT aiding without GNSS (validation).

The 15/20-state error-state EKF of :mod:`workbench.nav.land_ins` (paper 001 eq. 1-47) runs
twice, on the raw samples and on the samples compensated with the set; its process noise and
initial bias sigmas come from the set's noise block and bias sigmas (raw: the grade-free
``raw_*`` priors). The block's bias instability is, per triad (``bias_model``, :mod:`workbench.nav.bias_model`),
a ladder of three Gauss-Markov states a decade apart around the block's Allan minimum whose summed Allan
deviation is the flicker floor (``ladder``, the default), one Gauss-Markov state (``gauss_markov``: sigma
1.076 B, correlation time at the Allan minimum / 1.893), each beside the rate random walk, or
(``random_walk``) spread into the bias random walk. No GNSS is used; the drive's GPS fixes, where present, are the reference the
horizontal error is measured against (the paper's SPAN reference), in metres and % of the
distance travelled (the GPS track length).

Recording (``workbench run land-ins --rig sim``): the simulated vehicle drives paper 001's
pre-calibration profile (a rest for the alignment, four 90° heading changes with a stop after
each) and then ``cruise_s`` at ``speed_mps`` with a constant heading rate ``heading_rate_dps``
(sec. 4.2, Fig. 4-2/4-3). The initial heading is given from outside (``initial_heading_deg``;
default the drive's start heading from the session, i.e. a perfect gyrocompass) with 1-sigma
``heading_sigma_deg``.

``result.json``: ``raw`` and ``calibrated`` blocks with ``final_error_m``, ``final_error_pct_dt``,
``final_sigma_m`` (the filter's own horizontal 1-sigma, RSS), ``max_error_m``, ``distance_m``,
``heading_change_deg``, ``zupt_fraction``, ``nhc_fraction``, ``mean_weight`` (the M-estimator's),
``gyro_bias_final`` rad/s, ``accel_bias_final`` m/s², ``boresight_final`` rad, ``lever_arm_final`` m.
"""

from __future__ import annotations

import numpy as np

from workbench.calset import CalibrationSet
from workbench.earth import radii
from workbench.errors import AnalysisError
from workbench.nav.compensate import check_calibration, compensate, imu_samples, process_noise
from workbench.nav.land_ins import GradeErrors, LandInsConfig, run_land_ins
from workbench.nav.land_ins_model import BIAS_MODELS, bias_instability_states
from workbench.nav.lns import track_length
from workbench.nav.road import gps_fixes, thin
from workbench.options import Option, check_options, defaults
from workbench.procedure import ProcedureResult
from workbench.session import Session

NAME = "land-ins"
TITLE = "Land INS with NHC, ZUPT and ZARUPT, raw vs calibrated (validation, paper 001)"
TRIADS = ("accel", "gyro")
CAMPAIGN_ORDER = None
DRIVE = True
OPTIONS = (
    Option("heading_rate_dps", "sequence", "float", 0.3, "constant heading rate of the cruise", unit="deg/s"),
    Option("cruise_s", "sequence", "float", 3600.0, "cruise duration", unit="s", gt=0),
    Option("speed_mps", "sequence", "float", 20.0, "cruise speed", unit="m/s", gt=0),
    Option("precalibration", "sequence", "bool", True, "pre-calibration profile before the cruise"),
    Option("latitude_deg", "sequence", "float", 40.0, "start latitude", unit="deg", ge=-89.0, le=89.0),
    Option("longitude_deg", "sequence", "float", 33.0, "start longitude", unit="deg"),
    Option("height_m", "sequence", "float", 900.0, "start height", unit="m"),
    Option("heading0_deg", "sequence", "float", 0.0, "start heading", unit="deg"),
    Option("initial_heading_deg", "analysis", "float", None, "external initial heading (unset: the drive's)",
           unit="deg"),
    Option("heading_sigma_deg", "analysis", "float", 0.5, "1-sigma of the initial heading", unit="deg", gt=0),
    Option("update_s", "analysis", "float", 1.0, "filter step", unit="s", gt=0),
    Option("nhc_sigma_mps", "analysis", "float", 0.05, "NHC measurement 1-sigma", unit="m/s", gt=0),
    Option("zupt_sigma_mps", "analysis", "float", 0.01, "ZUPT measurement 1-sigma", unit="m/s", gt=0),
    Option("c0", "analysis", "float", 1.0, "M-estimator c0 (eq. 47)", gt=0),
    Option("c1", "analysis", "float", 6.0, "M-estimator c1 (eq. 47)", gt=0),
    Option("gain_scaling", "analysis", "bool", True, "M-estimator gain scaling (eq. 46-47)"),
    Option("states", "analysis", "int", 20, "15 (no boresight / lever arm), 20 (paper 001), 29 (+ gyro scale factor "
           "and misalignment) or 38 (+ the accelerometer's)", choices=(15, 20, 29, 38)),
    Option("raw_scale_prior_ppm", "analysis", "float", 1000.0, "scale-factor prior of the raw run (29 / 38 states)",
           unit="ppm", gt=0),
    Option("raw_misalignment_prior_mrad", "analysis", "float", 1.0, "misalignment prior of the raw run "
           "(29 / 38 states)", unit="mrad", gt=0),
    Option("raw_gyro_bias_prior_deg_h", "analysis", "float", 20.0, "gyro bias prior of the raw run",
           unit="deg/h", gt=0),
    Option("raw_accel_bias_prior_mg", "analysis", "float", 5.0, "accelerometer bias prior of the raw run",
           unit="mg", gt=0),
    Option("bias_model", "analysis", "str", "ladder", "the set's bias instability as a ladder of Gauss-Markov states, "
           "one Gauss-Markov state or spread into the bias random walk", choices=BIAS_MODELS),
    Option("force", "analysis", "bool", False, "accept a set of another serial"),
)
DEFAULTS = defaults(OPTIONS)


def road(heading_rate_dps: float, cruise_s: float, speed_mps: float, precalibration: bool) -> list[dict]:
    """The legs of the drive (lab units)."""
    from workbench.sim.roads import constant_rate_drive

    return constant_rate_drive(heading_rate_dps, speed_mps, cruise_s, precalibration)


def legs(**options) -> list[dict]:
    """The road legs (lab units) the simulated vehicle drives for the sequence ``options``."""
    o = check_options(NAME, OPTIONS, options, "sequence")
    return road(o["heading_rate_dps"], o["cruise_s"], o["speed_mps"], o["precalibration"])


def record_drive(truth, seed: int, out_dir, **options) -> Session:
    """Simulate the drive of ``options`` with the unit ``truth`` into ``out_dir``; returns the session."""
    from workbench.session import Site, load_session
    from workbench.sim.vehicle import drive, drive_config

    o = check_options(NAME, OPTIONS, options, "sequence")
    cfg = drive_config(legs(**options), Site(o["latitude_deg"], o["longitude_deg"], o["height_m"]), o["heading0_deg"])
    drive(cfg, truth, seed, out_dir, procedure=NAME)
    return load_session(out_dir)


def sequence(spec, **options):
    """A drive is recorded by the simulated vehicle, not by the turntable."""
    from workbench.errors import ProcedureError

    raise ProcedureError(f"{NAME}: recorded on the simulated vehicle (workbench run {NAME} --rig sim), "
                         "or analysed from a drive session (workbench analyze)")


def _grade(cal: CalibrationSet, calibrated: bool, noise, o) -> GradeErrors:
    """What the filter is told: noise from the set (the bias instability as ``o["bias_model"]`` says); bias
    sigmas from the set (calibrated: 2 x the set's bias sigma (+) bias instability) or the raw priors."""
    if calibrated:
        sig = {t: np.hypot(cal.triads[t].sigma_of("bias"), np.nan_to_num(cal.noise_term(t, "bias_instability")))
               for t in ("gyro", "accel")}
        ba = np.where(np.isfinite(sig["accel"]) & (sig["accel"] > 0), 2 * sig["accel"], o.si("raw_accel_bias_prior_mg"))
        bg = np.where(np.isfinite(sig["gyro"]) & (sig["gyro"] > 0), 2 * sig["gyro"], o.si("raw_gyro_bias_prior_deg_h"))
    else:
        ba, bg = np.full(3, o.si("raw_accel_bias_prior_mg")), np.full(3, o.si("raw_gyro_bias_prior_deg_h"))
    scale, mis = {}, {}
    for t in ("gyro", "accel"):  # the scale-factor states' priors: 2 x the set's sigmas, else the raw priors
        sm = cal.triads[t].sigma_of("scale_misalignment") if calibrated else np.full((3, 3), np.nan)
        off = np.where(np.eye(3, dtype=bool), np.nan, sm)
        scale[t] = np.where(np.isfinite(np.diag(sm)), 2 * np.diag(sm), o.si("raw_scale_prior_ppm"))
        worst = np.nanmax(np.where(np.isfinite(off), off, -np.inf), axis=1)
        mis[t] = np.where(np.isfinite(worst) & (worst > 0), 2 * worst, o.si("raw_misalignment_prior_mrad"))
    walk, markov = {"gyro": noise.gyro_bias_rw, "accel": noise.accel_bias_rw}, {}
    for t, white in (("gyro", noise.gyro_white), ("accel", noise.accel_white)):
        rrw = np.nan_to_num(cal.noise_term(t, "rrw"))
        if o["bias_model"] != "random_walk":
            walk[t] = rrw
        markov[t] = bias_instability_states(o["bias_model"], white, cal.noise_term(t, "bias_instability"), rrw,
                                            cal.noise_term(t, "quantization"), cal.noise_term(t, "rate_ramp"))
    return GradeErrors(ba, bg, noise.accel_white, noise.gyro_white, walk["accel"], walk["gyro"],
                       scale["gyro"], mis["gyro"], scale["accel"], mis["accel"], *markov["gyro"], *markov["accel"])


def analyze(session: Session, calibration: CalibrationSet | None = None, **options) -> ProcedureResult:
    """Raw and calibrated land-INS runs over the drive (module docstring)."""
    o = check_options(NAME, OPTIONS, options, "analysis")
    warnings = check_calibration(calibration, session.unit.serial, ("gyro", "accel"), bool(o["force"]), NAME)
    if not session.steps_of_kind("drive"):
        raise AnalysisError(f"{session.name}: no drive step (a session of the simulated vehicle or an imported drive)")
    drive_opts = session.options.get("drive") or {}
    if o["initial_heading_deg"] is not None:
        heading0 = float(o.si("initial_heading_deg"))
    elif "heading0" in drive_opts:
        heading0 = float(drive_opts["heading0"])
    else:
        raise AnalysisError(f"{session.name}: no initial heading: pass initial_heading_deg")
    site = session.site
    raw = imu_samples(session.samples, session.sample_rate_hz, session.name)
    noise = process_noise(calibration, fallback=raw)
    warnings += list(noise.notes)
    gps = gps_fixes(session)
    blocks, payload = {}, {"runs": {}}
    for mode in ("raw", "calibrated"):
        samples = compensate(raw, calibration, ("gyro", "accel")) if mode == "calibrated" else raw
        cfg = LandInsConfig(update_s=o["update_s"], nhc_sigma=o["nhc_sigma_mps"], zupt_sigma=o["zupt_sigma_mps"],
                            c0=o["c0"] if o["gain_scaling"] else None, c1=o["c1"], states=int(o["states"]),
                            yaw0=float(o.si("heading_sigma_deg")))
        res = run_land_ins(samples, site.latitude, float(np.radians(site.longitude_deg)), site.height_m, heading0,
                           _grade(calibration, mode == "calibrated", noise, o), cfg)
        blocks[mode] = _block(res, gps)
        payload["runs"][mode] = {"t": res.t, "lat": res.lat, "lon": res.lon, "sigma_n": res.sigma[:, 0],
                                 "sigma_e": res.sigma[:, 1], **blocks[mode].pop("_series")}
    if gps is not None:
        payload["gps"] = gps[["t", "lat", "lon"]].to_dict("list")
    series = {m: {"t": thin(r["t"]), "sigma_m": thin(np.hypot(r["sigma_n"], r["sigma_e"])),
                  **({"t_ref": thin(r["t_ref"]), "error_m": thin(r["error_m"])} if "error_m" in r else {})}
              for m, r in payload["runs"].items()}
    result = {**blocks, "series": series, "calibration_id": calibration.id, "states": int(o["states"]),
              "gain_scaling": {"on": bool(o["gain_scaling"]), "c0": o["c0"], "c1": o["c1"]}}
    if gps is None:
        warnings.append("no GPS fixes in the session: no reference, errors not measured")
    return ProcedureResult(NAME, result, None, payload, _summary(blocks), warnings)


def _block(res, gps) -> dict:
    """Figures of one run; errors against the GPS fixes when the session has them."""
    moving = res.mode == "nhc"
    heading = np.unwrap(res.rph[:, 2])
    block = {
        "final_sigma_m": float(np.hypot(res.sigma[-1, 0], res.sigma[-1, 1])),
        "heading_change_deg": float(np.degrees(np.abs(np.diff(heading))[moving[1:]].sum())),
        "zupt_fraction": float(np.mean(res.mode == "zupt")), "nhc_fraction": float(np.mean(moving)),
        "mean_weight": float(np.mean(res.weights_min)),
        "gyro_bias_final": res.gyro_bias[-1].tolist(), "accel_bias_final": res.accel_bias[-1].tolist(),
        "boresight_final": res.boresight[-1].tolist(), "lever_arm_final": res.lever_arm[-1].tolist(),
        "final_error_m": None, "final_error_pct_dt": None, "max_error_m": None, "distance_m": None,
        "_series": {},
    }
    if gps is None or len(gps) < 2:
        return block
    gt = gps["t"].to_numpy()
    sel = (gt >= res.t[0]) & (gt <= res.t[-1])
    lat, lon = np.interp(gt[sel], res.t, res.lat), np.interp(gt[sel], res.t, res.lon)
    rm, rn = radii(lat)
    err = np.hypot((lat - gps["lat"].to_numpy()[sel]) * rm, (lon - gps["lon"].to_numpy()[sel]) * rn * np.cos(lat))
    dist = track_length(gps["lat"].to_numpy()[sel], gps["lon"].to_numpy()[sel])
    block.update({"final_error_m": float(err[-1]), "max_error_m": float(err.max()), "distance_m": float(dist[-1]),
                  "final_error_pct_dt": float(100 * err[-1] / dist[-1]) if dist[-1] > 0 else None,
                  "_series": {"t_ref": gt[sel], "error_m": err}})
    return block


def _summary(blocks: dict) -> list[str]:
    lines = []
    for mode, b in blocks.items():
        if b["final_error_m"] is None:
            lines.append(f"{mode}: filter sigma {b['final_sigma_m']:.1f} m at the end (no reference)")
            continue
        lines.append(f"{mode}: final horizontal error {b['final_error_m']:.1f} m ({b['final_error_pct_dt']:.3f} % of "
                     f"{b['distance_m'] / 1000:.1f} km; filter 1-sigma {b['final_sigma_m']:.1f} m), "
                     f"heading change {b['heading_change_deg']:.0f}°, ZUPT {100 * b['zupt_fraction']:.0f} % / "
                     f"NHC {100 * b['nhc_fraction']:.0f} % of the steps")
    return lines


def figures(result: ProcedureResult) -> dict:
    """Horizontal error and the filter's sigma over time (paper 001 Fig. 4-4 style)."""
    from workbench.plots.lns import land_ins_figures

    return land_ins_figures(result.payload) if result.payload else {}
