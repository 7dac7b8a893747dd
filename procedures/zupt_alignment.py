"""ZUPT fine alignment on the table: validate a calibration set the way a land navigator uses it.

Sequence: the unit static on the table at each of ``positions`` (``[mount, table angle °]``,
like thesis Fig. 3.3-3.4), ``dwell_s`` each. With ``turns`` > 0 each position is followed by
that many table turns of ``turn_deg`` (90° by default), each followed by a hold of ``dwell_s``:
paper 001's pre-calibration profile on a turntable (sec. 4: stop after every 90° heading change
until the initial azimuth is reached), which makes the heading observable.

Analysis (``workbench analyze zupt-alignment SESSION --calibration SET``): for every position,
the thesis' ZUPT alignment (:func:`workbench.nav.zupt.align`, thesis sec. 3.3) runs twice, on
the raw samples and on the samples compensated with the set (:func:`workbench.nav.compensate`),
the process noise from the set's noise block in both runs. With turns, one alignment runs
through the position's hold and its turns: zero-velocity (and ZARUPT at the holds) updates,
the mechanisation following the turns (:func:`workbench.nav.zupt.align` with ``still``).
``heading_source``: ``external`` (default), or ``gyrocompass`` (no external heading: the heading
from the Earth rate; the error model is linearised at the closed-form gyrocompass through every hold,
:func:`workbench.nav.gyrocompass.indexed_gyrocompass`, so a wide or missing heading stays consistent);
``attitude_hold`` holds all three angles at the frozen solution (thesis eq. 3.57) instead of the
heading only (positions without turns). The external heading, as in the thesis: the table's
(``table_zero_azimuth_deg`` overrides the site's, e.g. with a
north-finding result; ``heading_sigma_deg`` is its 1-sigma). The table is the truth: attitude
errors against ``Session.attitude``, gyro-bias errors against the bias measured on the table
(mean output minus the known Earth rate over the last ``bias_reference_s`` of the position: the
bias wanders, so the filter's final estimate is compared with its recent value), NED velocity
(truly zero).

``result.json``: ``raw`` and ``calibrated`` blocks with ``roll_error_deg``, ``pitch_error_deg``,
``heading_error_deg`` (worst position, final), ``roll_error_60s_deg`` / ``pitch_error_60s_deg``
(worst, 60 s after the EKF start), ``velocity_error_mps`` (worst norm of the final NED
velocity), ``convergence_time_s`` (worst; null = never: the time after which the free mechanisation
drifts no more than 5x the white sensor noise over each correction interval, the thesis'
"indicates itself to be at rest and non-rotating"), ``gyro_bias_error`` (rad/s per axis, of
the position with the largest error) and ``positions`` (per position details, with ``turns``
and ``initial_heading_error_deg``: the reference heading the alignment started from (the external
one while it is held, else the closed-form gyrocompass weighted with the external heading) minus the
table's; ``attitude_sigma_deg``; ``tilt_observed`` and ``level_sigma_deg``: at
rest the tilt and the horizontal accelerometer bias are one quantity, so the roll / pitch sigma
stays at that bias's prior / g while the level against the accelerometers is known to
``level_sigma_deg``, said in the warnings; the turns separate them); ``heading_source``.
"""

from __future__ import annotations

import numpy as np

from workbench import units
from workbench.angles import wrap_pi
from workbench.calset import CalibrationSet
from workbench.errors import AnalysisError, ProcedureError
from workbench.json_values import json_value
from workbench.nav import zupt
from workbench.nav.compensate import check_calibration, compensate, imu_samples, process_noise
from workbench.nav.strapdown import attitude_errors, euler_rph
from workbench.nav.truth import reference_gyro_bias, table_truth
from workbench.options import Option, check_options, defaults
from workbench.procedure import ProcedureResult
from workbench.sequence import Hold, Index, Sequence, mount_matrix
from workbench.session import Session

NAME = "zupt-alignment"
TITLE = "ZUPT fine alignment on the table, raw vs calibrated (validation)"
TRIADS = ("accel", "gyro")
CAMPAIGN_ORDER = None  # a validation run, not a calibration step
OPTIONS = (
    Option("positions", "sequence", "list", [["z-down", 0.0], ["z-down", 90.0], ["y-down", 45.0]],
           "static positions [mount, table angle °]"),
    Option("dwell_s", "sequence", "float", 180.0, "hold per position", unit="s", gt=0),
    Option("level_s", "analysis", "float", 5.0, "coarse levelling before the EKF", unit="s", gt=0),
    Option("update_interval_s", "analysis", "float", 1.0, "ZUPT correction interval", unit="s", gt=0),
    Option("turns", "sequence", "int", 0, "table turns after each position's hold (each then held dwell_s)",
           ge=0, le=1000),
    Option("turn_deg", "sequence", "float", 90.0, "angle of each turn", unit="deg"),
    Option("zarupt", "analysis", "bool", False, "add the zero angular rate update"),
    Option("heading_source", "analysis", "str", "external", "external: the table's heading; gyrocompass: none "
           "given, from the Earth rate", choices=("external", "gyrocompass")),
    Option("attitude_hold", "analysis", "bool", False, "hold roll, pitch and heading (thesis eq. 3.57), not the "
           "heading only"),
    Option("gain_scaling", "analysis", "bool", True, "thesis gain scaling of the EKF"),
    Option("heading_sigma_deg", "analysis", "float", 0.1, "1-sigma of the heading given from outside", unit="deg",
           gt=0),
    Option("bias_reference_s", "analysis", "float", 60.0, "the table's gyro-bias reference over the last this of "
           "each position", unit="s", gt=0),
    Option("table_zero_azimuth_deg", "analysis", "float", None, "overrides the site's (e.g. a north-finding "
           "result)", unit="deg"),
    Option("raw_gyro_bias_prior_dps", "analysis", "float", 1.0, "gyro bias prior of the raw run", unit="deg/s",
           gt=0),
    Option("raw_accel_bias_prior_mg", "analysis", "float", 20.0, "accelerometer bias prior of the raw run",
           unit="mg", gt=0),
    Option("force", "analysis", "bool", False, "use a calibration set of another serial"),
)
DEFAULTS = defaults(OPTIONS)
_G0 = units.G0


def sequence(spec, **options) -> Sequence:
    """A static hold of ``dwell_s`` at each ``[mount, table angle °]`` of ``positions``."""
    o = check_options(NAME, OPTIONS, options, "sequence")
    steps = []
    if not o["positions"] or not all(isinstance(p, (list, tuple)) and len(p) == 2 and isinstance(p[1], (int, float))
                                     and not isinstance(p[1], bool) for p in o["positions"]):
        raise ProcedureError(f"{NAME}: positions={o['positions']!r}: expected [mount, table angle °] pairs, "
                             "e.g. [[\"z-down\", 0], [\"y-down\", 45]]")
    for mount, angle_deg in o["positions"]:
        mount_matrix(mount)  # raises on an unknown mount
        steps.append(Hold(mount=mount, table_angle=float(np.radians(angle_deg)), dwell_s=float(o["dwell_s"]),
                          label=f"{mount} {float(angle_deg):g}°"))
        steps += [Index(float(np.radians(o["turn_deg"])), float(o["dwell_s"]),
                        label=f"{mount} {float(angle_deg):g}° + {(k + 1) * o['turn_deg']:g}°") for k in range(o["turns"])]
    return Sequence(NAME, steps, dict(o))


def _priors(cal: CalibrationSet, noise_triad: str, calibrated: bool, raw_prior: float) -> np.ndarray:
    """Bias prior (3,): raw = the option; calibrated = 2 x (set's bias sigma (+) bias instability).

    The factor 2 covers what neither holds (turn-on repeatability, thermal residuals); an axis
    the set did not observe falls back to the raw prior.
    """
    if not calibrated:
        return np.full(3, raw_prior)
    sig = cal.triads[noise_triad].sigma_of("bias")
    bi = np.nan_to_num(cal.noise_term(noise_triad, "bias_instability"))
    prior = 2.0 * np.hypot(sig, bi)
    return np.where(np.isfinite(prior) & (prior > 0), prior, raw_prior)


def _position(session: Session, group: list, samples, noise, cfg: zupt.ZuptConfig, az, ref_s: float) -> dict:
    """Run the alignment on one position (its static step and the turns after it) and compare it with the table."""
    labels = session.samples["step"].to_numpy()
    step = group[0]
    inside = np.nonzero(np.isin(labels, [g.index for g in group]))[0]
    rows = np.arange(inside[0], inside[-1] + 1)  # with the transitions between the turns
    truth = table_truth(session, rows, az)
    true_rph = euler_rph(truth.attitude[0])
    df = session.samples
    still = (np.abs(df["table_rate"].to_numpy()[rows]) < 1e-9 if "table_rate" in df.columns
             else np.isin(labels[rows], [g.index for g in group if g.kind == "static"]))
    res = zupt.align(samples, noise, session.site.latitude, float(true_rph[2]), session.site.height_m, cfg,
                     still=still if len(group) > 1 else None)
    last = np.nonzero(labels[rows] == group[-1].index)[0]
    k0 = max(int(round(cfg.level_s / samples.dt)) if len(group) == 1 else 0,
             len(last) - int(round(ref_s / samples.dt)))
    sel = last[k0:][still[last[k0:]]]
    ref, ref_sig = reference_gyro_bias(samples.gyro[sel], table_truth(session, rows[sel], az), session.site.latitude)
    at_epochs = truth.attitude[np.minimum(np.searchsorted(samples.t, res.t), len(rows) - 1)]
    err = np.degrees(attitude_errors(res.attitude, at_epochs))
    i60 = min(len(res.t) - 1, int(np.searchsorted(res.t - res.t_start, 60.0)))
    conv = res.convergence_time()
    return {
        "label": step.label, "step": step.index, "true_rph_deg": np.degrees(true_rph).tolist(),
        "turns": sum(g.kind == "index" for g in group), "initial_heading_error_deg": _num(np.degrees(
            wrap_pi(true_rph[2] - res.initial_rph[2]))),
        "roll_error_deg": _num(err[-1, 0]), "pitch_error_deg": _num(err[-1, 1]),
        "heading_error_deg": _num(err[-1, 2]),
        "roll_error_60s_deg": _num(err[i60, 0]), "pitch_error_60s_deg": _num(err[i60, 1]),
        "attitude_sigma_deg": np.degrees(res.attitude_sigma[-1]).tolist(),
        "level_sigma_deg": np.degrees(res.level_sigma).tolist(), "tilt_observed": res.tilt_observed,
        "velocity_error_mps": float(np.linalg.norm(res.velocity[-1])),
        "convergence_time_s": conv,
        "gyro_bias": res.gyro_bias[-1].tolist(), "gyro_bias_sigma": res.gyro_bias_sigma[-1].tolist(),
        "gyro_bias_reference": ref.tolist(), "gyro_bias_reference_sigma": ref_sig.tolist(),
        "gyro_bias_error": (res.gyro_bias[-1] - ref).tolist(),
        "accel_bias": res.accel_bias[-1].tolist(), "accel_bias_sigma": res.accel_bias_sigma[-1].tolist(),
    }, res, err


def _groups(session: Session) -> list[list]:
    """Positions: each static step with the turns that follow it (an index step and the hold it plans after it)."""
    groups, prev = [], None
    for st in session.steps:
        if st.kind == "index" and groups:
            groups[-1].append(st)
        elif st.kind == "static" and prev is not None and prev.kind == "index" and groups:
            groups[-1].append(st)
        elif st.kind == "static":
            groups.append([st])
        prev = st
    return groups


def _num(x: float) -> float | None:
    """A JSON number, or None where the value is undefined (Euler roll/heading at pitch ±90°)."""
    return json_value(float(x))


def _block(positions: list[dict]) -> dict:
    """Worst case over positions (attitude, velocity, convergence) plus the per-position list."""
    def worst(key):
        vals = [p[key] for p in positions if p[key] is not None]
        return max(vals, key=abs) if vals else None

    conv = [p["convergence_time_s"] for p in positions]
    worst_bias = max(positions, key=lambda p: np.linalg.norm(p["gyro_bias_error"]))
    return {
        **{k: worst(k) for k in ("roll_error_deg", "pitch_error_deg", "heading_error_deg", "roll_error_60s_deg",
                                 "pitch_error_60s_deg")},
        "velocity_error_mps": max(p["velocity_error_mps"] for p in positions),
        "convergence_time_s": None if any(c is None for c in conv) else max(conv),
        "gyro_bias_error": worst_bias["gyro_bias_error"], "gyro_bias_sigma": worst_bias["gyro_bias_sigma"],
        "positions": positions,
    }


def analyze(session: Session, calibration: CalibrationSet | None = None, **options) -> ProcedureResult:
    """Raw and calibrated ZUPT alignment at each static position (see the module docstring)."""
    o = check_options(NAME, OPTIONS, options, "analysis")
    warnings = check_calibration(calibration, session.unit.serial, ("gyro", "accel"), bool(o["force"]), NAME)
    steps = session.steps_of_kind("static")
    if not steps:
        raise AnalysisError(f"{session.name}: no static step to align on")
    groups = _groups(session)
    turning = any(len(g) > 1 for g in groups)
    first = imu_samples(session.step_samples(steps[0].index), session.sample_rate_hz,
                        f"{session.name}: step {steps[0].index}")
    noise = process_noise(calibration, fallback=first)
    warnings += list(noise.notes)
    az = None if o["table_zero_azimuth_deg"] is None else float(np.radians(o["table_zero_azimuth_deg"]))
    held = () if (turning or o["heading_source"] == "gyrocompass") else \
        (("attitude",) if o["attitude_hold"] else ("heading",))
    if o["attitude_hold"] and not held:
        raise AnalysisError(f"{NAME}: attitude_hold needs positions without turns and an external heading")
    measurements = ("position", "velocity", *held) + (("zarupt",) if o["zarupt"] else ())
    blocks, payload = {}, {"t": [], "labels": [g[0].label or f"step {g[0].index}" for g in groups]}
    for mode in ("raw", "calibrated"):
        cfg = zupt.ZuptConfig(
            level_s=float(o["level_s"]), update_interval_s=float(o["update_interval_s"]), measurements=measurements,
            gain_scaling=bool(o["gain_scaling"]), heading_sigma=float(np.radians(o["heading_sigma_deg"])),
            heading_source=o["heading_source"],
            gyro_bias_prior=tuple(_priors(calibration, "gyro", mode == "calibrated",
                                          np.radians(o["raw_gyro_bias_prior_dps"]))),
            accel_bias_prior=tuple(_priors(calibration, "accel", mode == "calibrated",
                                           o["raw_accel_bias_prior_mg"] * 1e-3 * _G0)))
        rows, runs = [], []
        for group in groups:
            st = group[0]
            if len(group) == 1:
                data = session.step_samples(st.index)
            else:
                labels = session.samples["step"].to_numpy()
                inside = np.nonzero(np.isin(labels, [g.index for g in group]))[0]
                data = session.samples.iloc[inside[0]:inside[-1] + 1]
            raw = imu_samples(data, session.sample_rate_hz, f"{session.name}: step {st.index}")
            samples = compensate(raw, calibration, ("gyro", "accel")) if mode == "calibrated" else raw
            row, res, err = _position(session, group, samples, noise, cfg, az, float(o["bias_reference_s"]))
            rows.append(row)
            runs.append({"result": res, "errors_deg": err})
            warnings += [f"{mode} {row['label']}: {w}" for w in res.warnings] if mode == "calibrated" else []
        blocks[mode] = _block(rows)
        payload[mode] = runs
    result = {"raw": blocks["raw"], "calibrated": blocks["calibrated"], "calibration_id": calibration.id,
              "measurements": list(measurements), "update_interval_s": float(o["update_interval_s"]),
              "heading_source": o["heading_source"]}
    return ProcedureResult(NAME, result, None, payload, _summary(blocks), warnings)


def _summary(blocks: dict) -> list[str]:
    lines = []
    for mode, b in blocks.items():
        conv = "never" if b["convergence_time_s"] is None else f"{b['convergence_time_s']:.0f} s"
        lines.append(f"{mode}: roll {b['roll_error_deg']:+.3f}°, pitch {b['pitch_error_deg']:+.3f}°, "
                     f"heading {b['heading_error_deg']:+.3f}° (worst position), |v_NED| "
                     f"{b['velocity_error_mps'] * 1e3:.2f} mm/s, converged after {conv}; gyro bias estimated "
                     + ", ".join(f"{units.to_unit(v, 'deg/h'):+.1f}" for v in b["positions"][0]["gyro_bias"])
                     + " °/h (first position), error against the table "
                     + ", ".join(f"{units.to_unit(v, 'deg/h'):+.2f}" for v in b["gyro_bias_error"]) + " °/h")
    return lines


def figures(result: ProcedureResult) -> dict:
    """Thesis Fig. 3.6-3.10 for each position, raw vs calibrated (empty without a payload)."""
    from workbench.plots.nav import zupt_figures

    return zupt_figures(result.payload) if result.payload else {}
