"""Carousel north-finding: continuous rotation for whole laps, azimuth from the Earth-rate sinusoid.

The table turns at ``rate_deg_s`` for ``laps`` laps; the gyro outputs, binned by 5° of table
angle (the arc averaging is modelled), are fitted with ``b + A cos(a) + B sin(a)`` (shared
azimuth over the level axes, linear bias drift on by default), over all laps and per lap.
Bias and drift do not bias the azimuth; scale factor cancels between the two axes.
Product: a result.
"""

from __future__ import annotations

import numpy as np

from procedures import _northfinding
from workbench.errors import RigLimitError
from workbench.options import Option, check_options, defaults
from workbench.plots.northfinding import procedure_figures
from workbench.sequence import Carousel, Hold, Sequence, with_options

NAME = "carousel"
TITLE = "Carousel north-finding (continuous rotation)"
TRIADS = ("gyro",)
CAMPAIGN_ORDER = None
OPTIONS = (
    Option("rate_deg_s", "sequence", "float", 10.0, "table rate (clockwise if > 0; non-zero)", unit="deg/s"),
    Option("laps", "sequence", "int", 10, "whole laps", ge=1, le=1000),
    _northfinding.START_OFFSET,
    _northfinding.MOUNT,
    _northfinding.settle_option(0.0),
    *_northfinding.ANALYSIS_OPTIONS,
)
DEFAULTS = defaults(OPTIONS)


def sequence(spec, **options) -> Sequence:
    """A short hold at the start angle, then ``laps`` whole laps at ``rate_deg_s`` (clockwise if > 0)."""
    o = check_options(NAME, OPTIONS, options, "sequence")
    rate_deg_s, laps, start_offset_deg, mount, settle_s = (o[k] for k in ("rate_deg_s", "laps", "start_offset_deg",
                                                                        "mount", "settle_s"))
    if rate_deg_s == 0 or int(laps) < 1:
        raise RigLimitError(f"{NAME}: rate_deg_s must be non-zero and laps >= 1 (got {rate_deg_s}, {laps})")
    lap_s = 360.0 / abs(rate_deg_s)
    if settle_s >= lap_s:
        raise RigLimitError(f"{NAME}: settle_s {settle_s:g} s is not shorter than one lap ({lap_s:g} s)")
    steps = [Hold(mount, np.radians(start_offset_deg), 5.0, "start"),
             Carousel(None, np.radians(rate_deg_s), int(laps), "carousel")]
    return with_options(Sequence(NAME, steps), rate_deg_s=rate_deg_s, laps=int(laps),
                        start_offset_deg=start_offset_deg, settle_s=settle_s)


def analyze(session, **options):
    """Sinusoid fit of the binned carousel data, over all laps and per lap."""
    return _northfinding.analyze(NAME, "carousel", OPTIONS, session, options)


def figures(result) -> dict:
    """Gyro output vs table angle with the fitted sinusoid, azimuth per lap."""
    return procedure_figures(result.payload)
