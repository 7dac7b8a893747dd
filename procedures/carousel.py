"""Carousel north-finding: continuous rotation for whole laps, azimuth from the Earth-rate sinusoid.

The table turns at ``rate_deg_s`` for ``laps`` laps; the gyro outputs, binned by 5° of table
angle (the arc averaging is modelled), are fitted with ``b + A cos(a) + B sin(a)`` (shared
azimuth over the level axes, linear bias drift on by default), over all laps and per lap.
Bias and drift do not bias the azimuth; scale factor cancels between the two axes.
Product: a result.
"""

from __future__ import annotations

import numpy as np

from workbench.analysis.northfinding import analyze_procedure
from workbench.errors import RigLimitError
from workbench.plots.northfinding import procedure_figures
from workbench.sequence import Carousel, Hold, Sequence, with_options

NAME = "carousel"
TITLE = "Carousel north-finding (continuous rotation)"
TRIADS = ("gyro",)
CAMPAIGN_ORDER = None
DEFAULTS = {"rate_deg_s": 10.0, "laps": 10, "start_offset_deg": 0.0, "mount": "z-down", "settle_s": 0.0}


def sequence(spec, rate_deg_s: float = 10.0, laps: int = 10, start_offset_deg: float = 0.0, mount="z-down",
             settle_s: float = 0.0, **_analysis_options) -> Sequence:
    """A short hold at the start angle, then ``laps`` whole laps at ``rate_deg_s`` (clockwise if > 0)."""
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
    return analyze_procedure(NAME, "carousel", session, DEFAULTS, options)


def figures(result) -> dict:
    """Gyro output vs table angle with the fitted sinusoid, azimuth per lap."""
    return procedure_figures(result.payload)
