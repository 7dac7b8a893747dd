"""Redundant-gyro configuration simulated from 45° steps (thesis sec. 4.4.3, sequences 8-12).

The two-axis gyro holds 0°, 45°, ..., 315° for 60 s each, for 10 turns. Two consecutive
positions give a skewed four-axis configuration (axes at psi, psi+45°, psi+90°, psi+135°):
eight pairings (0-45, ..., 315-0) per turn, each an azimuth from least squares after the
bias is removed (a known bias, option ``bias`` rad/s, or the mean over complete turns).
Reported per pairing with its spread over turns (table 4.4 across sessions). Product: a result.
"""

from __future__ import annotations

import numpy as np

from procedures import _northfinding
from workbench.errors import RigLimitError
from workbench.options import Option, check_options, defaults
from workbench.plots.northfinding import procedure_figures
from workbench.sequence import Hold, Index, Repeat, Sequence, with_options

NAME = "redundant"
TITLE = "Redundant-gyro configuration from 45° steps"
TRIADS = ("gyro",)
CAMPAIGN_ORDER = None
OPTIONS = (
    Option("dwell_s", "sequence", "float", 60.0, "hold per 45° position", unit="s", gt=0),
    Option("turns", "sequence", "int", 10, "turns through the eight positions", ge=1, le=1000),
    _northfinding.START_OFFSET,
    _northfinding.MOUNT,
    _northfinding.settle_option(2.0),
    _northfinding.DISCARD,
    *(o for o in _northfinding.ANALYSIS_OPTIONS if o.name != "positions_per_turn"),  # eight, by the method
)
DEFAULTS = defaults(OPTIONS)
STEP = np.pi / 4  # rad, 45° between positions


def sequence(spec, **options) -> Sequence:
    """``turns`` clockwise turns through the eight 45° positions, ``dwell_s`` each."""
    o = check_options(NAME, OPTIONS, options, "sequence")
    dwell_s, turns, start_offset_deg, mount, settle_s = (o[k] for k in ("dwell_s", "turns", "start_offset_deg",
                                                                      "mount", "settle_s"))
    if not dwell_s > settle_s:
        raise RigLimitError(f"{NAME}: dwell_s {dwell_s:g} s is not longer than the settling time settle_s "
                            f"{settle_s:g} s")
    if int(turns) < 1:
        raise RigLimitError(f"{NAME}: turns {turns} must be >= 1")
    first = Hold(mount, np.radians(start_offset_deg), dwell_s, "0")
    steps = [*_northfinding.warm_up(first, o["discard_s"]), first, Repeat([Index(STEP, dwell_s)], 8 * int(turns) - 1)]
    return with_options(Sequence(NAME, steps), dwell_s=dwell_s, turns=int(turns), start_offset_deg=start_offset_deg,
                        settle_s=settle_s, discard_s=o["discard_s"])


def analyze(session, **options):
    """The eight pairings of every turn, their means and spreads."""
    declared = (*OPTIONS, Option("positions_per_turn", "analysis", "int", 8, "eight 45° positions", choices=(8,)))
    return _northfinding.analyze(NAME, "redundant", declared, session, {**options, "positions_per_turn": 8})


def figures(result) -> dict:
    """Gyro output vs table angle and the azimuth per pairing and turn (thesis Fig. 4.16-4.23)."""
    return procedure_figures(result.payload)
