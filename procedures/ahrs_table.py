"""AHRS on the table: attitude from gyros + accelerometer + magnetometer, raw vs calibrated (validation).

Sequence: for each tilted mount of ``mounts`` (``[roll °, pitch °]``): a hold, a rotation at
``rates_dps[0]`` for ``rotate_s``, an index by ``index_deg``, a rotation at ``rates_dps[1]``,
a hold (``dwell_s`` each hold). Two mounts with the defaults: about 10 minutes.

Analysis (``workbench analyze ahrs-table SESSION --calibration SET``): both AHRS filters of
:mod:`workbench.nav.ahrs` (Kalman with gyro-bias states, complementary) run on the raw samples
and on the samples compensated with the set, re-initialised at each mount (a remount moves the
unit by hand). The process and accelerometer measurement noise come from the set's noise block
(the same for both runs); the errors left in the samples from the set (its coefficients for
the raw run, their sigmas for the calibrated one): gyro scale/misalignment (an apparent bias that
moves with the rate), accelerometer and magnetometer bias and ``M`` per element (constant body-frame
errors: coloured tilt and heading measurement noise of the Kalman filter, see
:func:`workbench.nav.ahrs.kalman`);
the magnetometer white noise from the samples; the declination from
``declination_deg`` or the rig configuration. The table is the truth (``Session.attitude`` with
the encoder angle), evaluated at the filters' update epochs inside the steps.

``result.json``: ``raw`` and ``calibrated`` blocks (the Kalman filter's figures; the
complementary filter's in a nested ``complementary`` block) with ``roll_error_deg``,
``pitch_error_deg``, ``heading_error_deg`` (RMS over the sequence), ``*_max_deg``,
``velocity_error_mps`` (null: an AHRS has no velocity), ``convergence_time_s`` (worst mount:
time after which the heading error stays within ``heading_tol_deg`` and roll and pitch within
``tilt_tol_deg``; null = never), ``gyro_bias_error`` (rad/s per axis, end of the last mount,
against the table reference: the mean output minus the known rate over the mount's last static
step) and ``gyro_bias_sigma`` (the filter's and the reference's in quadrature).

Magnetic disturbances (``mag_rejection``, on by default; :mod:`workbench.nav.ahrs`): the field's
norm and dip are checked against the reference (the set's field norm for the calibrated run, the
first second of each mount otherwise; the dip from the first second) and the heading innovation
is gated. Each block reports ``mag_disturbed_s`` (time the field was off the reference),
``mag_refused_s`` (time the heading measurement was refused, by the check or the gate) and
``mag_disturbances`` (the detected intervals, ``[start, end]`` s); ``heading_max_deg`` is then the
heading excursion a disturbance left.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from workbench import units
from workbench.calset import CalibrationSet
from workbench.errors import AnalysisError, ProcedureError
from workbench.nav import ahrs
from workbench.nav.compensate import check_calibration, compensate, imu_samples, process_noise
from workbench.nav.strapdown import attitude_errors
from workbench.nav.truth import mount_segments, reference_gyro_bias, table_truth
from workbench.rigsites import declination
from workbench.options import Option, check_options, defaults
from workbench.procedure import ProcedureResult
from workbench.sequence import Hold, Index, Rotate, Sequence, mount_from_euler
from workbench.session import Session

NAME = "ahrs-table"
TITLE = "AHRS through table rate and tilt steps, raw vs calibrated (validation)"
TRIADS = ("accel", "gyro", "mag")
CAMPAIGN_ORDER = None  # a validation run, not a calibration step
OPTIONS = (
    Option("mounts", "sequence", "list", [[10.0, -5.0], [-20.0, 15.0]], "tilted mounts [roll, pitch]", unit="deg"),
    Option("rates_dps", "sequence", "list", [20.0, -45.0], "the two rotation rates of each mount", unit="deg/s"),
    Option("rotate_s", "sequence", "float", 120.0, "duration of each rotation", unit="s", gt=0),
    Option("index_deg", "sequence", "float", 90.0, "index between the rotations", unit="deg"),
    Option("dwell_s", "sequence", "float", 20.0, "each hold", unit="s", gt=0),
    Option("update_interval_s", "analysis", "float", 0.1, "filter update interval", unit="s", gt=0),
    Option("declination_deg", "analysis", "float", None, "magnetic declination (default: the rig "
           "configuration's)", unit="deg"),
    Option("tau_tilt_s", "analysis", "float", 5.0, "complementary filter tilt time constant", unit="s", gt=0),
    Option("tau_heading_s", "analysis", "float", 20.0, "complementary filter heading time constant", unit="s",
           gt=0),
    Option("heading_tol_deg", "analysis", "float", 1.0, "converged: heading error within this", unit="deg", gt=0),
    Option("tilt_tol_deg", "analysis", "float", 0.2, "converged: roll and pitch errors within this", unit="deg",
           gt=0),
    Option("mag_rejection", "analysis", "bool", True, "reject magnetometer updates in a magnetic disturbance "
           "(workbench.nav.ahrs)"),
    Option("force", "analysis", "bool", False, "use a calibration set of another serial"),
)
DEFAULTS = defaults(OPTIONS)
_FILTERS = ("kalman", "complementary")


def sequence(spec, **options) -> Sequence:
    """Per tilted mount: hold, rotate, index, rotate back the other way, hold."""
    o = check_options(NAME, OPTIONS, options, "sequence")
    if "mag" not in getattr(spec, "triads", ("mag",)):
        raise ProcedureError(f"{NAME}: the unit has no magnetometer (the AHRS heading needs one)")
    rates = o["rates_dps"]
    if len(rates) != 2 or not all(isinstance(r, (int, float)) and not isinstance(r, bool) and r != 0 for r in rates):
        raise ProcedureError(f"{NAME}: rates_dps={rates!r} (deg/s) must be two non-zero rates (out, back)")
    mounts = o["mounts"]
    if not mounts or not all(isinstance(m, (list, tuple)) and len(m) == 2 and all(
            isinstance(a, (int, float)) and not isinstance(a, bool) and abs(a) <= 180 for a in m) for m in mounts):
        raise ProcedureError(f"{NAME}: mounts={mounts!r} (deg) must be a list of [roll, pitch] pairs, each within ±180")
    r1, r2 = (float(np.radians(r)) for r in rates)
    steps = []
    for roll, pitch in o["mounts"]:
        mount = mount_from_euler("YX", [pitch, roll])
        tag = f"roll {roll:g}° pitch {pitch:g}°"
        steps += [Hold(mount=mount, table_angle=0.0, dwell_s=float(o["dwell_s"]), label=f"{tag} hold"),
                  Rotate(mount=mount, rate=r1, revolutions=None, duration_s=float(o["rotate_s"]),
                         label=f"{tag} {o['rates_dps'][0]:g}°/s"),
                  Index(angle=float(np.radians(o["index_deg"])), dwell_s=float(o["dwell_s"]),
                        label=f"{tag} index {o['index_deg']:g}°"),
                  Rotate(mount=mount, rate=r2, revolutions=None, duration_s=float(o["rotate_s"]),
                         label=f"{tag} {o['rates_dps'][1]:g}°/s"),
                  Hold(mount=mount, dwell_s=float(o["dwell_s"]), label=f"{tag} final hold")]
    return Sequence(NAME, steps, dict(o))


def _convergence(t: np.ndarray, err: np.ndarray, heading_tol: float, tilt_tol: float) -> float | None:
    """Time from ``t[0]`` after which |heading error| < heading_tol and |roll|, |pitch| < tilt_tol (deg)."""
    ok = (np.abs(err[:, 2]) < heading_tol) & (np.abs(err[:, 0]) < tilt_tol) & (np.abs(err[:, 1]) < tilt_tol)
    if len(ok) == 0 or not ok[-1]:
        return None
    bad = np.nonzero(~ok)[0]
    return float(t[0 if len(bad) == 0 else bad[-1] + 1] - t[0])


def _residual(cal: CalibrationSet, triad: str, calibrated: bool) -> tuple[np.ndarray, np.ndarray]:
    """Per-element 1-sigma of the bias (3,) (SI unit of the triad) and of ``M`` (3, 3) left in a triad's samples.

    Raw: the magnitude of the set's own coefficients (what compensation would remove);
    calibrated: their 1-sigma (the raw figure where the set did not observe an element).
    """
    tc = cal.triads[triad]
    out = []
    for name in ("bias", "scale_misalignment"):
        val = np.abs(np.asarray(getattr(tc.model, name), float))
        if calibrated:
            sig = tc.sigma_of(name)
            val = np.where(np.isfinite(sig), sig, val)
        out.append(val)
    return out[0], out[1]


def _run_filter(name: str, session: Session, samples, rows, noise, cfg, o, scale_sigma: float) -> dict:
    """One filter over one mount segment: epochs in steps, attitude errors (deg), bias error."""
    res = ahrs.kalman(samples, noise, session.site.latitude, cfg, scale_sigma=scale_sigma) if name == "kalman" \
        else ahrs.complementary(samples, session.site.latitude, cfg)
    idx = rows[np.searchsorted(samples.t, res.t)]
    truth = table_truth(session, idx)
    err = np.degrees(attitude_errors(res.attitude, truth.attitude))
    keep = truth.in_step
    labels = session.samples["step"].to_numpy()[rows]
    static = [s.index for s in session.steps_of_kind("static") if np.any(labels == s.index)]
    if not static:
        raise AnalysisError(f"{session.name}: a mount without a static step: no gyro-bias reference")
    sel = np.nonzero(labels == static[-1])[0]
    ref, ref_sig = reference_gyro_bias(samples.gyro[sel], table_truth(session, rows[sel]), session.site.latitude)
    return {"t": res.t[keep], "errors_deg": err[keep],
            "convergence_time_s": _convergence(res.t, err, o["heading_tol_deg"], o["tilt_tol_deg"]),
            "gyro_bias_error": res.gyro_bias[-1] - ref, "gyro_bias_sigma": res.gyro_bias_sigma[-1],
            "reference_sigma": ref_sig, "mag_disturbed_s": float(np.sum(res.mag_disturbed)) * cfg.update_interval_s,
            "mag_refused_s": float(np.sum(res.mag_weight == 0.0)) * cfg.update_interval_s,
            "mag_disturbances": [list(iv) for iv in res.disturbed_intervals()]}


def _metrics(segs: list[dict]) -> dict:
    err = np.vstack([s["errors_deg"] for s in segs])
    rms = np.sqrt(np.nanmean(err ** 2, axis=0))
    peak = np.nanmax(np.abs(err), axis=0)
    conv = [s["convergence_time_s"] for s in segs]
    last = segs[-1]
    return {"roll_error_deg": float(rms[0]), "pitch_error_deg": float(rms[1]), "heading_error_deg": float(rms[2]),
            "roll_max_deg": float(peak[0]), "pitch_max_deg": float(peak[1]), "heading_max_deg": float(peak[2]),
            "velocity_error_mps": None,
            "convergence_time_s": None if any(c is None for c in conv) else max(conv),
            "gyro_bias_error": last["gyro_bias_error"].tolist(),
            "gyro_bias_sigma": np.hypot(last["gyro_bias_sigma"], last["reference_sigma"]).tolist(),
            "mag_disturbed_s": sum(s["mag_disturbed_s"] for s in segs),
            "mag_refused_s": sum(s["mag_refused_s"] for s in segs),
            "mag_disturbances": [iv for s in segs for iv in s["mag_disturbances"]]}


def analyze(session: Session, calibration: CalibrationSet | None = None, **options) -> ProcedureResult:
    """Raw and calibrated AHRS runs against the table (see the module docstring)."""
    o = check_options(NAME, OPTIONS, options, "analysis")
    warnings = check_calibration(calibration, session.unit.serial, TRIADS, bool(o["force"]), NAME)
    if not session.has_mag:
        raise AnalysisError(f"{session.name}: samples have no magnetometer columns mx, my, mz (the AHRS needs them)")
    raw_all = imu_samples(session.samples, session.sample_rate_hz, session.name)
    noise = process_noise(calibration, fallback=raw_all)
    warnings += list(noise.notes)
    base = ahrs.AhrsConfig(update_interval_s=float(o["update_interval_s"]),
                           declination=declination(session, o["declination_deg"]),
                           tau_tilt_s=float(o["tau_tilt_s"]), tau_heading_s=float(o["tau_heading_s"]),
                           mag_rejection=bool(o["mag_rejection"]))
    cal_all = compensate(raw_all, calibration, TRIADS)
    blocks, payload = {}, {}
    for mode, data in (("raw", raw_all), ("calibrated", cal_all)):
        calibrated = mode == "calibrated"
        (ab, am), (mb, mm) = (_residual(calibration, tr, calibrated) for tr in ("accel", "mag"))
        cfg = replace(base, accel_bias_error=ab, accel_scale_error=am, mag_bias_error_ut=mb, mag_scale_error=mm,
                      mag_reference_norm_ut=calibration.triads["mag"].field_norm_ut if calibrated else None)
        gyro_scale = float(np.sqrt(np.mean(_residual(calibration, "gyro", calibrated)[1] ** 2)))
        per_filter = {name: [] for name in _FILTERS}
        for rows in mount_segments(session):
            seg = data.slice(int(rows[0]), int(rows[-1]) + 1)
            for name in _FILTERS:
                per_filter[name].append(_run_filter(name, session, seg, rows, noise, cfg, o, gyro_scale))
        block = _metrics(per_filter["kalman"])
        block["complementary"] = _metrics(per_filter["complementary"])
        blocks[mode] = block
        payload[mode] = {name: {"t": np.concatenate([s["t"] for s in segs]),
                                "errors_deg": np.vstack([s["errors_deg"] for s in segs])}
                         for name, segs in per_filter.items()}
    result = {"raw": blocks["raw"], "calibrated": blocks["calibrated"], "calibration_id": calibration.id,
              "declination_deg": float(np.degrees(base.declination)), "update_interval_s": base.update_interval_s}
    return ProcedureResult(NAME, result, None, payload, _summary(blocks), warnings)


def _summary(blocks: dict) -> list[str]:
    lines = []
    for mode, b in blocks.items():
        for name, m in (("kalman", b), ("complementary", b["complementary"])):
            err, sig = np.array(m["gyro_bias_error"]), np.array(m["gyro_bias_sigma"], float)
            z = "" if not np.all(np.isfinite(sig)) else " (" + ", ".join(f"{v:+.1f}" for v in err / sig) + " sigma)"
            lines.append(f"{mode} {name}: RMS roll {m['roll_error_deg']:.3f}°, pitch {m['pitch_error_deg']:.3f}°, "
                         f"heading {m['heading_error_deg']:.2f}° (max {m['heading_max_deg']:.2f}°); "
                         + (f"magnetometer refused {m['mag_refused_s']:.1f} s; " if m["mag_refused_s"] else "")
                         + "gyro-bias error "
                         + ", ".join(f"{units.to_unit(v, 'deg/h'):+.1f}" for v in err) + f" °/h{z}")
    return lines


def figures(result: ProcedureResult) -> dict:
    """Attitude errors against the table, raw vs calibrated, per filter (empty without a payload)."""
    from workbench.plots.nav import ahrs_figures

    return ahrs_figures(result.payload) if result.payload else {}
