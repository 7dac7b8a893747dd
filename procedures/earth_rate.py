"""Earth-rate sweep: full turns in equal steps, the horizontal Earth rate as a sinusoid (thesis seq. 0).

Thesis table 4.2 sequence 0: four full turns in 10° steps, 60 s per position. The analysis
fits ``b + A cos(a) + B sin(a)`` (shared through the azimuth across the level axes, with an
optional linear drift) to all positions and to each turn: the amplitude is checked against
``Omega_e cos(lat)`` (Fig. 4.6) and the phase gives the azimuth. Product: a result.
"""

from __future__ import annotations

import numpy as np

from procedures import _northfinding
from workbench.errors import RigLimitError
from workbench.options import Option, check_options, defaults
from workbench.plots.northfinding import procedure_figures
from workbench.sequence import Hold, Index, Repeat, Sequence, with_options

NAME = "earth-rate"
TITLE = "Earth-rate sweep (full turns in steps)"
TRIADS = ("gyro",)
CAMPAIGN_ORDER = None
OPTIONS = (
    Option("dwell_s", "sequence", "float", 60.0, "hold per position", unit="s", gt=0),
    Option("step_deg", "sequence", "float", 10.0, "index between positions (divides 360° into >= 3)", unit="deg",
           ge=0.1, le=120.0),
    Option("turns", "sequence", "int", 4, "full turns", ge=1, le=1000),
    _northfinding.START_OFFSET,
    _northfinding.MOUNT,
    _northfinding.settle_option(2.0),
    *_northfinding.ANALYSIS_OPTIONS,
)
DEFAULTS = defaults(OPTIONS)


def sequence(spec, **options) -> Sequence:
    """``turns`` full turns clockwise in ``step_deg`` steps (360 / step_deg positions per turn), ``dwell_s`` each."""
    o = check_options(NAME, OPTIONS, options, "sequence")
    dwell_s, step_deg, turns, settle_s = o["dwell_s"], o["step_deg"], o["turns"], o["settle_s"]
    start_offset_deg, mount = o["start_offset_deg"], o["mount"]
    per = 360.0 / step_deg
    if not dwell_s > settle_s:
        raise RigLimitError(f"{NAME}: dwell_s {dwell_s:g} s is not longer than the settling time settle_s "
                            f"{settle_s:g} s")
    if abs(per - round(per)) > 1e-9 or round(per) < 3 or int(turns) < 1:
        raise RigLimitError(f"{NAME}: step_deg {step_deg:g} must divide 360° into at least 3 positions, turns >= 1")
    n = int(round(per)) * int(turns)
    steps = [Hold(mount, np.radians(start_offset_deg), dwell_s, "0"),
             Repeat([Index(np.radians(step_deg), dwell_s)], n - 1)]
    return with_options(Sequence(NAME, steps), dwell_s=dwell_s, step_deg=step_deg, turns=int(turns),
                        start_offset_deg=start_offset_deg, settle_s=settle_s)


def analyze(session, **options):
    """Sinusoid fit of all positions (drift on by default) and one per turn."""
    return _northfinding.analyze(NAME, "multiposition", OPTIONS, session, options)


def figures(result) -> dict:
    """Gyro output vs table angle with the fitted Earth-rate sinusoids (thesis Fig. 4.6), azimuth per turn."""
    return procedure_figures(result.payload)
