"""Thermal sweep: bias and scale factor of the gyro and accelerometer against temperature.

Two chamber profiles:

* ``profile="soak"``: setpoints from ``t_min_c`` to ``t_max_c`` in ``step_c`` steps (and back
  down when ``return_sweep``), each held until the unit's own temperature settles (the rig
  ends a Soak step on the unit thermometer), then a six-position static set (``dwell_s`` each)
  and, with ``rate_dps``, rotations at ±rate about three axes for the gyro scale factor.
* ``profile="ramp"``: a soak at ``t_min_c``, a continuous ramp at ``ramp_c_per_min`` to
  ``t_max_c`` (and back when ``return_sweep``), the unit static (``mount``) or indexing
  through the six positions every ``ramp_dwell_s``. Give ``reference`` (a calibration JSON,
  e.g. from the turntable procedures) so the ramp fit removes ``M`` and the gyro g-sensitivity
  ``G f``; without it the ramp "bias" of each position includes them.

Analysis: :func:`workbench.analysis.thermal.analyze_thermal` (per-soak turntable fits, or a
direct fit of bias against the unit temperature for ramps; cross-validated polynomial order;
hysteresis). ``accel_bias_instability_mg`` / ``gyro_bias_instability_deg_h``: the unit's Allan
bias instability B (the campaign passes its Allan result's), the floor of each soak's bias sigma;
``accel_rrw_m_s_h_sqrt_h`` / ``gyro_rrw_deg_h_sqrt_h``: its bias random walk K, whose wander since
the session start enters the sigmas of the bias polynomial's coefficients (``with_bias_random_walk``).
Product: a calibration set with the ``thermal`` block (t_ref ``t_ref_c``).
The default profile is short (seven soaks, -10..50 °C, up only) so it fits in a campaign;
use ``t_min_c=-40, t_max_c=85, step_c=15, return_sweep=True`` for a full qualification sweep.
"""

from __future__ import annotations

import numpy as np

from workbench.analysis.thermal import analyze_thermal
from workbench.calset import CalibrationSet
from workbench.errors import RigLimitError
from workbench.options import Option, check_options, defaults
from workbench.procedure import ProcedureResult
from workbench.sequence import Hold, Ramp, Rotate, Sequence, Soak, with_options

NAME = "thermal"
TITLE = "Thermal sweep (chamber soaks or ramps): bias and scale factor vs temperature"
TRIADS = ("accel", "gyro")
CAMPAIGN_ORDER = 40
OPTIONS = (
    Option("profile", "sequence", "str", "soak", "chamber profile: soaks at setpoints or a continuous ramp",
           choices=("soak", "ramp")),
    Option("t_min_c", "sequence", "float", -10.0, "lowest temperature", unit="°C"),
    Option("t_max_c", "sequence", "float", 50.0, "highest temperature", unit="°C"),
    Option("step_c", "sequence", "float", 10.0, "between soak setpoints", unit="°C", gt=0),
    Option("return_sweep", "sequence", "bool", False, "sweep back down too (hysteresis)"),
    Option("dwell_s", "sequence", "float", 10.0, "hold per position at each soak", unit="s", gt=0),
    Option("rate_dps", "sequence", "float", None, "rotations at ±rate about three axes at each soak (gyro scale "
           "factor)", unit="deg/s", gt=0),
    Option("ramp_c_per_min", "sequence", "float", 1.0, "ramp rate", unit="°C/min", gt=0),
    Option("ramp_dwell_s", "sequence", "float", None, "index through the six positions every this during a ramp",
           unit="s", gt=0),
    Option("mount", "sequence", "any", "z-down", "mount name or 3x3 body->table-top matrix"),
    Option("settle_tol_c_per_min", "both", "float", 0.05, "a soak has settled below this rate of change",
           unit="°C/min", gt=0),
    Option("settle_window_s", "both", "float", 120.0, "over this window", unit="s", gt=0),
    Option("t_ref_c", "analysis", "float", 25.0, "reference temperature of the model", unit="°C"),
    Option("max_order", "analysis", "int", 5, "highest polynomial order tried", ge=0),
    Option("order", "analysis", "int", None, "polynomial order (default: cross-validated)", ge=0),
    Option("hysteresis", "analysis", "str", "auto", "direction term", choices=("auto", "on", "off")),
    Option("order_per_axis", "analysis", "bool", True, "each axis its own cross-validated order (else one "
           "order for the triad)"),
    Option("ramp_window_s", "analysis", "float", 60.0, "averaging window of a ramp", unit="s", gt=0),
    Option("reference", "analysis", "str", None, "calibration JSON whose M and G the ramp fit removes"),
    Option("position_sigma_deg", "analysis", "float", 0.01, "1-sigma tilt of each position ('auto' estimates "
           "it)", unit="deg", ge=0, words=("auto",)),
    Option("accel_bias_instability_mg", "analysis", "magnitude", None, "accelerometer bias instability B "
           "(Allan), the floor of each soak's bias sigma", unit="mg"),
    Option("gyro_bias_instability_deg_h", "analysis", "magnitude", None, "gyro bias instability B (Allan)",
           unit="deg/h"),
    Option("accel_rrw_m_s_h_sqrt_h", "analysis", "magnitude", None, "accelerometer bias random walk K (Allan): "
           "its wander in the bias coefficients' sigmas", unit="m/s/h/sqrt(h)"),
    Option("gyro_rrw_deg_h_sqrt_h", "analysis", "magnitude", None, "gyro rate random walk K (Allan)",
           unit="deg/h/sqrt(h)"),
)
DEFAULTS = defaults(OPTIONS)
SIX = ("z-down", "z-up", "x-up", "x-down", "y-up", "y-down")
RATE_MOUNTS = ("z-down", "x-up", "y-up")
_ANALYSIS_KEYS = ("t_ref_c", "max_order", "order", "hysteresis", "order_per_axis", "settle_tol_c_per_min", "settle_window_s",
                  "ramp_window_s")


MAX_SETPOINTS = 1000  # soaks of one sweep: -40..85 °C every 0.125 °C; step_c=1e-9 asked numpy for 447 GiB


def setpoints(t_min_c: float, t_max_c: float, step_c: float, return_sweep: bool) -> list[float]:
    """Soak setpoints (°C): ``t_min_c`` up by ``step_c`` to ``t_max_c`` (included), then back down."""
    if not (step_c > 0 and t_max_c > t_min_c):
        raise RigLimitError(f"{NAME}: need t_max_c > t_min_c and step_c > 0 (got {t_min_c}, {t_max_c}, {step_c})")
    if not (t_max_c - t_min_c) / step_c < MAX_SETPOINTS:
        raise RigLimitError(f"{NAME}: step_c={step_c:g} °C makes {(t_max_c - t_min_c) / step_c:.3g} soaks from "
                            f"{t_min_c:g} to {t_max_c:g} °C; at most {MAX_SETPOINTS}")
    up = list(np.arange(t_min_c, t_max_c + 1e-9, step_c))
    if t_max_c - up[-1] > 1e-9:
        up.append(t_max_c)
    up = [float(t) for t in up]
    return up + up[-2::-1] if return_sweep else up


def sequence(spec, **options) -> Sequence:
    """The chamber profile (see the module docstring); soaks may last up to 12 thermal time constants."""
    o = check_options(NAME, OPTIONS, options, "sequence")
    profile, t_min_c, t_max_c, step_c, return_sweep, dwell_s, rate_dps, ramp_c_per_min, ramp_dwell_s, mount, \
        settle_tol_c_per_min, settle_window_s = (o[k] for k in (
            "profile", "t_min_c", "t_max_c", "step_c", "return_sweep", "dwell_s", "rate_dps", "ramp_c_per_min",
            "ramp_dwell_s", "mount", "settle_tol_c_per_min", "settle_window_s"))
    tau = float(getattr(spec, "thermal_time_constant_s", 600.0) or 600.0)
    max_s = max(4 * 3600.0, 12 * tau)
    steps: list = []
    if profile == "soak":
        for temp in setpoints(t_min_c, t_max_c, step_c, return_sweep):
            steps.append(Soak(temp, mount, 0.0, settle_tol_c_per_min, settle_window_s, max_s, f"soak {temp:g} °C"))
            steps += [Hold(m, 0.0, dwell_s, f"{temp:g} °C {m}") for m in SIX]
            if rate_dps:
                rate = np.radians(rate_dps)
                steps += [Rotate(m, sgn * rate, 1.0, None, f"{temp:g} °C {m} {sgn * rate_dps:+g} °/s")
                          for m in RATE_MOUNTS for sgn in (1, -1)]
    else:  # ramp
        positions = [[m, 0.0] for m in SIX] if ramp_dwell_s else None
        steps.append(Soak(t_min_c, mount, 0.0, settle_tol_c_per_min, settle_window_s, max_s, f"soak {t_min_c:g} °C"))
        steps.append(Ramp(t_max_c, ramp_c_per_min, mount, 0.0, positions, ramp_dwell_s, "ramp up"))
        if return_sweep:
            steps.append(Ramp(t_min_c, ramp_c_per_min, mount, 0.0, positions, ramp_dwell_s, "ramp down"))
    return with_options(Sequence(NAME, steps), profile=profile, t_min_c=t_min_c, t_max_c=t_max_c, step_c=step_c,
                        return_sweep=return_sweep, dwell_s=dwell_s, rate_dps=rate_dps,
                        ramp_c_per_min=ramp_c_per_min, ramp_dwell_s=ramp_dwell_s)


def analyze(session, **options) -> ProcedureResult:
    """Thermal analysis of a soak or ramp session -> calibration set with the thermal block."""
    opts = check_options(NAME, OPTIONS, options, "analysis")
    reference = None
    if opts["reference"]:  # a calibration JSON (e.g. turntable) for the ramp fit's M and G
        ref = CalibrationSet.load(opts["reference"])
        reference = {t: ref.model(t) for t in ("gyro", "accel") if t in ref.triads}
    result = analyze_thermal(session, reference=reference, **{k: opts[k] for k in _ANALYSIS_KEYS},
                             position_sigma=opts.si("position_sigma_deg"),
                             bias_instability={"accel": opts.si("accel_bias_instability_mg"),
                                               "gyro": opts.si("gyro_bias_instability_deg_h")},
                             bias_rrw={"accel": opts.si("accel_rrw_m_s_h_sqrt_h"),
                                       "gyro": opts.si("gyro_rrw_deg_h_sqrt_h")})
    return ProcedureResult(NAME, result.to_dict(), result.to_calibration(session.unit), result,
                           result.summary(), list(result.warnings))


def figures(result: ProcedureResult) -> dict:
    """Bias and scale factor vs temperature with the fits, and the residuals after compensation."""
    from workbench.plots.thermal import thermal_figures

    return thermal_figures(result.payload)
