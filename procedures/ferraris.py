"""Ferraris calibration: six static positions + one 360° turn about each axis, no encoder.

For hand-made sessions (e.g. imucal's recording, imported with
``fixtures/import_profiles/imucal_ferraris.yaml``) and for tables without a rate encoder.

Sequence: the six axis-up/down holds (``dwell_s``), then for x, y, z one turn of
``turn_deg`` (default -360°: clockwise seen from above with the axis up, i.e. negative
about the axis) at ``turn_rate_dps`` with the axis up.

Analysis (``workbench analyze ferraris SESSION_DIR``): accelerometer from the static
positions (:func:`workbench.analysis.turntable.fit_accel`, position tilt estimated when the
positions scatter beyond the noise, as hand-made positions do); gyro bias and g-sensitivity
from the same positions (:func:`fit_gyro_static`); gyro ``M`` from the integrated turns
against the known angle (:func:`workbench.analysis.gyro_fit.fit_gyro_turns`); and checks of
each turn (:func:`turn_checks`): integrated angle after compensation, closure, wobble,
tilt of the turn axis, motion just before and after the section.

Noise options as ``multiposition``: ``accel_bias_instability_mg`` and
``gyro_bias_instability_deg_h`` (the unit's Allan B, scalar or 3 axes), and
``gyro_nonlinearity_ppm_per_dps`` (1-sigma of the unit's nonlinearity, which turns at one rate
cannot separate from the scale factor). Without the accelerometer's B, its bias sigma includes
the largest bias instability the six dwells could hide (:func:`accel_without_floor_prior`):
six 10-s dwells of a MEMS accelerometer cannot show a floor that moves the bias by several
times the white noise of a dwell mean, and a warning alone left z-scores of 6 (measured over 10
seeds, industrial MEMS and consumer grades: rms z 3.3-3.9 before, 1.1 after).

Reference: Ferraris, Grimaldi, Parvis, "Procedure for effortless in-field calibration of
three-axis rate gyros and accelerometers", Sensors and Materials 7 (1995) (imucal's method).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from procedures._triad import result_dict
from workbench.analysis.gyro_fit import fit_gyro_turns, turn_checks
from workbench.analysis.turntable import TriadFit, fit_accel, fit_gyro_static
from workbench.calset import CalibrationSet
from workbench.errors import ProcedureError
from workbench.options import Option, check_options, defaults
from workbench.procedure import ProcedureResult
from workbench.sequence import Hold, Rotate, Sequence
from workbench.session import Session

NAME = "ferraris"
TITLE = "Ferraris: six positions + three 360° turns (hand-made or no encoder)"
TRIADS = ("accel", "gyro")
CAMPAIGN_ORDER = None
OPTIONS = (
    Option("dwell_s", "sequence", "float", 10.0, "hold per static position", unit="s", gt=0),
    Option("turn_deg", "sequence", "float", -360.0, "turn about each axis held up (negative: clockwise seen "
           "from above)", unit="deg"),
    Option("turn_rate_dps", "sequence", "float", 90.0, "rate of the turns", unit="deg/s", gt=0),
    Option("position_sigma_deg", "analysis", "float", "auto", "1-sigma tilt of each position ('auto' "
           "estimates it, as hand-made positions need)", unit="deg", ge=0, words=("auto",)),
    Option("earth_rate", "analysis", "str", "auto", "Earth rate in the gyro static fit",
           choices=("auto", "model", "ignore")),
    Option("settle_s", "analysis", "float", 0.0, "dropped at the start of each step", unit="s", ge=0),
    Option("window_s", "analysis", "float", 1.0, "window before and after each turn for the motion check",
           unit="s", gt=0),
    Option("accel_bias_instability_mg", "analysis", "magnitude", None, "the unit's accelerometer bias "
           "instability B (Allan), a floor for the bias wander the dwells cannot show", unit="mg"),
    Option("gyro_bias_instability_deg_h", "analysis", "magnitude", None, "the unit's gyro bias instability B "
           "(Allan)", unit="deg/h"),
    Option("gyro_nonlinearity_ppm_per_dps", "analysis", "magnitude", None, "1-sigma of the unit's gyro "
           "nonlinearity, included in the scale-factor sigma (turns at one rate cannot observe it)",
           unit="ppm/(deg/s)"),
)
DEFAULTS = defaults(OPTIONS)


def sequence(spec, **opts) -> Sequence:
    """Six holds, then one turn about each body axis held up (see the module docstring)."""
    o = check_options(NAME, OPTIONS, opts, "sequence")
    turn, rate = o["turn_deg"], o["turn_rate_dps"]
    if turn == 0:
        raise ProcedureError(f"{NAME}: turn_deg must be non-zero")
    steps: list = [Hold(m, 0.0, float(o["dwell_s"]), m)
                   for m in ("x-up", "x-down", "y-up", "y-down", "z-up", "z-down")]
    # with the axis up, a negative turn about it is a positive (clockwise) table rotation
    table_rate = float(np.radians(rate)) * -np.sign(turn)
    for axis in "xyz":
        steps.append(Rotate(f"{axis}-up", table_rate, abs(turn) / 360.0, label=f"{axis}_rot"))
    return Sequence(NAME, steps, options=dict(o))


def accel_without_floor_prior(session: Session, settle_s: float, tilt: float | str) -> TriadFit:
    """Accelerometer fit of the six positions whose bias sigma includes, on the axes where the
    dwells could hide one larger than that sigma, the largest bias instability they could hide
    (``notes["hidden_bias_instability"]`` of a first fit; m/s^2); the notes say so."""
    acc = fit_accel(session, None, "none", settle_s=settle_s, position_sigma=tilt)
    hidden = np.array([np.nan if v is None else v for v in acc.notes["hidden_bias_instability"]], float)
    if not np.isfinite(hidden).any():
        return acc
    acc = fit_accel(session, None, "none", settle_s=settle_s, position_sigma=tilt,
                    bias_instability=np.nan_to_num(hidden), warn_hidden_floor=False)
    return replace(acc, notes={**acc.notes, "bias_instability_assumed": hidden.tolist(),
                               "bias_instability_source": "the largest the dwells could hide (no "
                                                          "accel_bias_instability_mg given)"})


def analyze(session: Session, **opts) -> ProcedureResult:
    """Ferraris calibration of a session (see the module docstring)."""
    o = check_options(NAME, OPTIONS, opts, "analysis")
    settle = o["settle_s"]
    tilt = o.si("position_sigma_deg")
    accel_b = o.si("accel_bias_instability_mg")
    acc = (accel_without_floor_prior(session, settle, tilt) if accel_b is None else
           fit_accel(session, None, "none", settle_s=settle, position_sigma=tilt, bias_instability=accel_b))
    static = fit_gyro_static(session, None, o["earth_rate"], settle_s=settle,
                             bias_instability=o.si("gyro_bias_instability_deg_h"))
    gyr = fit_gyro_turns(session, static, acc, nonlinearity_sigma=o.si("gyro_nonlinearity_ppm_per_dps"))
    checks = turn_checks(session, gyr.model(), acc.model(), window_s=o["window_s"])
    calset = CalibrationSet(unit=session.unit, triads={"accel": acc.triad_calibration(), "gyro": gyr.triad_calibration()},
                            notes={NAME: {"accel": dict(acc.notes), "gyro": dict(gyr.notes),
                                          "turns": [c.to_dict() for c in checks]}})
    result = result_dict({"accel": acc, "gyro": gyr})
    result["turns"] = [c.to_dict() for c in checks]
    summary = acc.summary() + gyr.summary() + [
        f"turn {c.label}: compensated gyro turns {np.degrees(c.angle):.3f}° of the nominal "
        f"{np.degrees(np.linalg.norm(c.nominal)):.0f}°, "
        f"closure {np.degrees(c.closure):.3f}°, wobble {np.degrees(c.wobble_rms):.2f}° rms, "
        f"backward {np.degrees(c.backward):.2f}°, axis tilt {np.degrees(c.axis_tilt):.2f}°, "
        f"gravity change {np.degrees(c.gravity_change):.3f}°, motion before/after "
        f"{np.degrees(c.motion_before):.3f}°/{np.degrees(c.motion_after):.3f}°" for c in checks]
    return ProcedureResult(NAME, result=result, calibration=calset,
                           payload={"accel": acc, "gyro": gyr, "turns": checks}, summary=summary,
                           warnings=[*acc.warnings, *gyr.warnings])


def figures(result: ProcedureResult) -> dict:
    """Residuals per position and turn, and the turn checks."""
    from workbench.plots.turntable import plot_residuals, plot_turn_checks

    p = result.payload
    return {"accel_residuals": plot_residuals(p["accel"]), "gyro_residuals": plot_residuals(p["gyro"]),
            "turn_checks": plot_turn_checks(p["turns"])}
