"""Rate-table test: gyro scale factor, misalignment, nonlinearity and asymmetry.

Sequence: for each mount in ``mounts`` (default x-up, y-up, z-up: each body axis along the
table axis) and each rate in ``rates_fs`` (fractions of the gyro's full scale, capped by
``max_rate_dps``), the table turns clockwise then counter-clockwise for whole revolutions,
at least ``min_duration_s`` per direction.

Analysis (``workbench analyze rate SESSION_DIR``):
:func:`workbench.analysis.turntable.fit_gyro_rate` on all rate steps, against the encoder
rate (samples column ``table_rate``) plus the vertical Earth rate; ``position_sigma_deg`` is the
fixture's repeatability (1-sigma tilt of the table axis in the body, default 0.01°, ``"auto"``
to estimate it). Residuals in % of
``full_scale_dps`` (the gyro range stored by the sequence; else the largest test rate).
"""

from __future__ import annotations

import numpy as np

from procedures._triad import result_dict
from workbench.analysis.turntable import fit_gyro_rate
from workbench.calset import CalibrationSet
from workbench.errors import ProcedureError
from workbench.options import Option, check_options, defaults
from workbench.procedure import ProcedureResult
from workbench.sequence import Rotate, Sequence
from workbench.session import Session

NAME = "rate"
TITLE = "Rate table: gyro scale factor, misalignment, nonlinearity, asymmetry"
TRIADS = ("gyro",)
CAMPAIGN_ORDER = 30
OPTIONS = (
    Option("mounts", "sequence", "list", ["x-up", "y-up", "z-up"], "mounts, each putting a body axis along "
           "the table axis"),
    Option("rates_fs", "sequence", "list", [0.05, 0.2, 0.5, 0.9], "test rates as fractions of the gyro's "
           "full scale"),
    Option("max_rate_dps", "sequence", "float", 900.0, "cap on the test rates", unit="deg/s", gt=0),
    Option("min_duration_s", "sequence", "float", 10.0, "shortest rotation per direction (whole "
           "revolutions)", unit="s", gt=0),
    Option("full_scale_dps", "analysis", "float", None, "gyro full scale for the residuals in % (default: "
           "the range the sequence stored, else the largest rate)", unit="deg/s", gt=0),
    Option("position_sigma_deg", "analysis", "float", 0.01, "1-sigma tilt of the table axis in the body "
           "(fixture repeatability; 'auto' estimates it)", unit="deg", ge=0, words=("auto",)),
)
DEFAULTS = defaults(OPTIONS)


def rate_set(full_scale: float, rates_fs, max_rate: float) -> list[float]:
    """Positive test rates (rad/s): fractions of ``full_scale`` capped at ``max_rate``, distinct."""
    if not all(isinstance(f, (int, float)) and not isinstance(f, bool) for f in rates_fs):  # [[1, "a"]]: a TypeError
        raise ProcedureError(f"{NAME}: rates_fs={rates_fs!r}: expected a list of fractions of full scale")
    rates = sorted({round(float(min(f * full_scale, max_rate)), 12) for f in rates_fs})
    if not rates or rates[0] <= 0:
        raise ProcedureError(f"{NAME}: rates_fs must hold positive fractions of full scale")
    return rates


def sequence(spec, **opts) -> Sequence:
    """CW and CCW whole revolutions at each rate about each mount's table axis."""
    o = check_options(NAME, OPTIONS, opts, "sequence")
    if getattr(spec, "gyro", None) is None:
        raise ProcedureError(f"{NAME}: the unit has no gyro")
    fs = float(spec.gyro.range)
    rates = rate_set(fs, o["rates_fs"], o.si("max_rate_dps"))
    steps = []
    for mount in o["mounts"]:
        for r in rates:
            revs = max(1, int(np.ceil(o["min_duration_s"] * r / (2 * np.pi))))
            for sign, word in ((1, "CW"), (-1, "CCW")):
                steps.append(Rotate(mount, sign * r, float(revs), label=f"{mount} {word} {np.degrees(r):.0f}°/s"))
    return Sequence(NAME, steps, options={**o, "full_scale_dps": float(np.degrees(fs))})


def full_scale(session: Session, value) -> float:
    """Full scale (rad/s): the option, else the session's sequence option, else the largest rate."""
    if value is None:
        value = session.options.get("full_scale_dps")
    if value is not None:
        return float(np.radians(float(value)))
    return float(max(abs(s.table_rate) for s in session.steps_of_kind("rate")))


def analyze(session: Session, **opts) -> ProcedureResult:
    """Gyro rate fit of all rate steps (see the module docstring)."""
    o = check_options(NAME, OPTIONS, opts, "analysis")
    fit = fit_gyro_rate(session, position_sigma=o.si("position_sigma_deg"))
    fs = full_scale(session, o["full_scale_dps"])
    calset = CalibrationSet(unit=session.unit, triads={"gyro": fit.triad_calibration()},
                            notes={NAME: {"asymmetry": fit.asymmetry.tolist(),
                                          "asymmetry_sigma": [None if not np.isfinite(v) else float(v)
                                                              for v in fit.asymmetry_sigma],
                                          "note": "asymmetry (SF+ - SF-)/2 is not part of the error model; "
                                                  "M holds the mean scale factor"}})
    return ProcedureResult(NAME, result=result_dict({"gyro": fit}, fs), calibration=calset,
                           payload={"gyro": fit, "full_scale": fs}, summary=fit.summary(fs),
                           warnings=list(fit.warnings))


def figures(result: ProcedureResult) -> dict:
    """Residuals per step, compensated vs table rate, scale-factor error vs rate."""
    from workbench.plots.turntable import plot_rate_tracking, plot_residuals, plot_scale_factor_vs_rate

    fit, fs = result.payload["gyro"], result.payload["full_scale"]
    return {"gyro_residuals": plot_residuals(fit), "rate_tracking": plot_rate_tracking(fit, fs),
            "scale_factor_vs_rate": plot_scale_factor_vs_rate(fit)}
