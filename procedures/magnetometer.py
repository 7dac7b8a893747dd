"""Magnetometer calibration on the turntable: yaw sweeps at the fixture's tilts.

Sequence: for every tilt of the fixture (``tilts_deg``: [roll, pitch] pairs in degrees,
applied to the level z-down mount), either ``yaw_steps`` static holds evenly spaced over
360° (``mode="steps"``, ``dwell_s`` each) or one continuous revolution at ``rate_dps``
(``mode="continuous"``). The default fixture tilts ±30° about x and y; a level fixture
(``[[0, 0]]``) supports only the 2D method.

Analysis (``workbench analyze magnetometer SESSION_DIR``). A session with ``free`` steps (the unit
turned by hand) is fitted from its own accelerometer, never a table
(:mod:`workbench.analysis.mag_free`): constant-dip fit of hard/soft iron and the mag-to-IMU rotation,
printed with truth-free quality figures (field-norm RMS, field-to-gravity angle spread, in sample and
held out, beside a plain ellipsoid). Otherwise: the fit points from the session
(static means, ≤1° blocks of rotation), the estimator chosen automatically with its reason
(or ``method``), hard iron, soft iron, field norm, dip, declination, mag-to-IMU rotation and
heading error against the table azimuth (:mod:`workbench.analysis.magnetometer`). Options:
``field_norm_ut`` (the site's field, fixes the scale of I+M), ``declination_deg``,
``accel_calibration`` (a calibration JSON whose ``accel`` block compensates the accelerometer
used for the gravity direction), ``igrf`` (check the fitted norm and dip against the IGRF field
at the site and date), ``method``, ``robust`` (``auto``: raw-sample spikes are left out of the point means
and the fit turns robust when its residuals are heavy-tailed; ``true`` always, ``false`` never).
"""

from __future__ import annotations

import numpy as np

from workbench.analysis.mag_free import calibrate_free, hand_steps
from workbench.analysis.mag_select import METHODS
from workbench.analysis.magnetometer import calibrate, points_from_session, triad_calibration
from workbench.calset import CalibrationSet
from workbench.errors import AnalysisError, ProcedureError
from workbench.options import Option, check_options, defaults
from workbench.procedure import ProcedureResult
from workbench.sequence import Hold, Rotate, Sequence, mount_from_euler
from workbench.session import Session

NAME = "magnetometer"
TITLE = "Magnetometer hard/soft iron and heading (yaw sweeps at fixture tilts)"
TRIADS = ("mag", "accel")
CAMPAIGN_ORDER = 50
OPTIONS = (
    Option("tilts_deg", "sequence", "list", [[0.0, 0.0], [30.0, 0.0], [-30.0, 0.0], [0.0, 30.0], [0.0, -30.0]],
           "fixture tilts [roll, pitch] of the level z-down mount", unit="deg"),
    Option("mode", "sequence", "str", "steps", "static yaw steps or one continuous revolution per tilt",
           choices=("steps", "continuous")),
    Option("yaw_steps", "sequence", "int", 12, "static holds per tilt (mode steps)", ge=3, le=3600),
    Option("dwell_s", "sequence", "float", 5.0, "hold per yaw step", unit="s", gt=0),
    Option("rate_dps", "sequence", "float", 10.0, "rate of the revolution (mode continuous)", unit="deg/s"),
    Option("method", "analysis", "str", "auto", "estimator ('auto' chooses and says why)", choices=METHODS),
    Option("robust", "analysis", "bool", "auto", "leave out spikes and outlying points ('auto': when the "
           "residuals are heavy-tailed)", words=("auto",)),
    Option("field_norm_ut", "analysis", "float", None, "the site's field magnitude (fixes the scale of I+M; "
           "default: the rig site's)", unit="uT", gt=0),
    Option("declination_deg", "analysis", "float", None, "magnetic declination", unit="deg"),
    Option("accel_calibration", "analysis", "str", None, "calibration JSON whose accel block compensates the "
           "gravity direction"),
    Option("igrf", "analysis", "bool", False, "check the fitted norm and dip against the IGRF at the site"),
)
DEFAULTS = defaults(OPTIONS)


def _tilt_pairs(value) -> np.ndarray:
    """``tilts_deg`` as (N, 2) [roll, pitch] degrees; ProcedureError naming the value otherwise
    ([30], [[30, "a"]] and [1e10] were reshape / conversion tracebacks)."""
    try:
        tilts = np.asarray(value, float)
    except (TypeError, ValueError):
        tilts = np.zeros((0, 3))
    if tilts.ndim != 2 or tilts.shape[1] != 2 or not np.all(np.abs(tilts) <= 180.0):
        raise ProcedureError(f"{NAME}: tilts_deg={value!r}: expected [roll, pitch] pairs in degrees, "
                             "each within ±180, e.g. [[0, 0], [30, 0]]")
    return tilts


def sequence(spec, **options) -> Sequence:
    """Yaw sweeps (static steps or one continuous revolution) at each fixture tilt."""
    o = check_options(NAME, OPTIONS, options, "sequence")
    if getattr(spec, "mag", None) is None:
        raise ProcedureError(f"{NAME}: the unit has no magnetometer")
    tilts = _tilt_pairs(o["tilts_deg"])
    steps: list = []
    for roll, pitch in tilts:
        mount = mount_from_euler("xy", [roll, pitch])
        label = f"tilt roll {roll:g}° pitch {pitch:g}°"
        if o["mode"] == "steps":
            steps += [Hold(mount, float(a), o["dwell_s"], label)
                      for a in np.linspace(0, 2 * np.pi, o["yaw_steps"], endpoint=False)]
        else:
            steps += [Hold(mount, 0.0, float(o["dwell_s"]), label),
                      Rotate(mount, float(np.radians(o["rate_dps"])), 1.0, label=label)]
    return Sequence(NAME, steps, options={**o, "tilts_deg": tilts.tolist()})


def analyze(session: Session, **options) -> ProcedureResult:
    """Calibrate the magnetometer from a session of yaw sweeps (see the module docstring)."""
    o = check_options(NAME, OPTIONS, options, "analysis")
    decl = o.si("declination_deg")
    accel = None if o["accel_calibration"] is None else CalibrationSet.load(o["accel_calibration"]).model("accel")
    # the field magnitude: the option, else the reference the rig's site records, else unknown
    norm = o["field_norm_ut"] if o["field_norm_ut"] is not None else session.site.field_norm_ut
    norm = None if norm is None else float(norm)
    reference = _igrf(session) if o["igrf"] else None
    if hand_steps(session):  # by hand: gravity from the unit's own accelerometer, never the table
        cal = calibrate_free(session, method=str(o["method"]), robust=o["robust"], field_norm_ut=norm,
                             accel_model=accel, reference=reference)
    else:
        points = points_from_session(session, reject_spikes=o["robust"] is not False)
        cal = calibrate(points, method=str(o["method"]), robust=o["robust"], field_norm_ut=norm,
                        declination=decl, accel_model=accel, reference=reference, source=session.name)
    fit = cal.fit
    calset = CalibrationSet(unit=session.unit, triads={"mag": triad_calibration(fit)},
                            notes={NAME: {"method": fit.method, "reason": cal.choice.reason}})
    return ProcedureResult(NAME, result=cal.to_dict(), calibration=calset, payload=cal,
                           summary=cal.summary(), warnings=list(cal.warnings))


def _igrf(session: Session):
    """IGRF field at the session's site on the session's date (today if the manifest has none)."""
    from datetime import UTC, datetime

    from workbench.analysis.mag_reference import igrf_field

    try:
        date = datetime.fromisoformat(str(session.created).replace("Z", "+00:00")).replace(tzinfo=None)
    except ValueError:
        date = datetime.now(UTC).replace(tzinfo=None)
    s = session.site
    return igrf_field(s.latitude_deg, s.longitude_deg, s.height_m, date)


def figures(result: ProcedureResult) -> dict:
    """Point cloud (raw vs calibrated) and heading error vs table azimuth (paper 004 Fig. 15); for a hand-held
    fit, the field norm and field-to-gravity angle against time instead of the heading error."""
    from workbench.plots.magnetometer import plot_cloud, plot_heading_error

    if result.payload is None:
        raise AnalysisError(f"{NAME}: the result carries no fit to draw (payload missing)")
    if result.payload.free_quality is not None:
        from workbench.plots.mag_free import plot_free_quality

        return {"mag_cloud": plot_cloud(result.payload), "mag_free_quality": plot_free_quality(result.payload.free_quality)}
    return {"mag_cloud": plot_cloud(result.payload), "mag_heading_error": plot_heading_error(result.payload)}
