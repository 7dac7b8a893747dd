"""Maytagging north-finding: home and 180° positions alternated, azimuth per pair (thesis eq. 4.6).

Thesis table 4.2 sequences 1-7: home, then 180° clockwise, 60 s per position, 40 pairs,
starting at the home position (offset 0°) or 90° from it. ``ordering`` ABAB alternates the
two positions every dwell (an index per dwell); ABBA holds each position for two dwells
(pairs (A, B), (B, A), ...: half the indexes, and a linear drift cancels over each pair of
pairs). The product is a result (azimuth with its uncertainty beside the theoretical
figures), not a calibration set.

:func:`applies` says whether a grade resolves the Earth rate (a pair's noise-limited
azimuth 1-sigma below 0.1 rad); the campaign runs this procedure only then.
"""

from __future__ import annotations

import numpy as np

from procedures import _northfinding
from workbench.analysis.northfinding_fit import PAIRINGS
from workbench.analysis.northfinding_theory import adev_model, pair_azimuth_sigma
from workbench.errors import RigLimitError
from workbench.options import Option, check_options, defaults
from workbench.plots.northfinding import procedure_figures
from workbench.sequence import Hold, Index, Repeat, Sequence, with_options

NAME = "maytagging"
TITLE = "North-finding by maytagging (±180° indexing)"
TRIADS = ("gyro",)
CAMPAIGN_ORDER = 60
OPTIONS = (
    Option("dwell_s", "sequence", "float", 60.0, "hold per position", unit="s", gt=0),
    Option("count", "sequence", "int", 40, "pairs of positions (even for ABBA)", ge=1, le=10000),
    Option("ordering", "sequence", "str", "ABAB", "ABAB: an index per dwell; ABBA: each position held two dwells",
           choices=("ABAB", "ABBA")),
    _northfinding.START_OFFSET,
    _northfinding.MOUNT,
    _northfinding.settle_option(2.0),
    _northfinding.DISCARD,
    Option("pairs", "analysis", "str", "disjoint", "disjoint: pairs (1, 2), (3, 4), ... (independent); sliding: "
           "(1, 2), (2, 3), ..., an azimuth every dwell (thesis sec. 4.4.2, ABAB only)", choices=PAIRINGS),
    *_northfinding.ANALYSIS_OPTIONS,
)
DEFAULTS = defaults(OPTIONS)
APPLIES_MAX_PAIR_SIGMA = 0.1  # rad: a pair must locate north to ~6° for the method to make sense
APPLIES_LATITUDE = np.radians(45.0)  # rad, reference latitude of the applicability test


def applies(spec) -> bool:
    """True when the grade's gyros resolve the Earth rate: pair 1-sigma < 0.1 rad at 45° with the default dwell.

    Uses the grade's noise terms (ADEV at the dwell with the turn's dead time, IEEE 952) of its first two
    sensing axes.
    """
    g = spec.specs.get("gyro")
    if g is None:
        return False
    nz = g.noise
    adev = adev_model(DEFAULTS["dwell_s"] - DEFAULTS["settle_s"], nz.white, nz.bias_instability, nz.rrw,
                      nz.quantization, spacing=DEFAULTS["dwell_s"] + np.pi / Index(np.pi).index_rate)
    axes = list(g.sensing_axes)[:2]
    sigma = pair_azimuth_sigma(adev[axes[0]], APPLIES_LATITUDE, adev[axes[-1]] if len(axes) > 1 else None,
                               None if len(axes) > 1 else np.pi / 2)
    return sigma < APPLIES_MAX_PAIR_SIGMA


def sequence(spec, **options) -> Sequence:
    """``count`` pairs of positions A (the start offset) and B = A + 180°, ``dwell_s`` each.

    The table turns clockwise to B and back counter-clockwise (mechanical stops). ABBA
    needs an even ``count``.
    """
    o = check_options(NAME, OPTIONS, options, "sequence")
    dwell_s, count, ordering, settle_s = o["dwell_s"], o["count"], o["ordering"], o["settle_s"]
    start_offset_deg, mount = o["start_offset_deg"], o["mount"]
    if not dwell_s > settle_s:
        raise RigLimitError(f"{NAME}: dwell_s {dwell_s:g} s is not longer than the settling time settle_s "
                            f"{settle_s:g} s")
    if ordering == "ABBA" and count % 2:
        raise RigLimitError(f"{NAME}: count {count} must be even for ABBA")
    a = Hold(mount, np.radians(start_offset_deg), dwell_s, "A")
    to_b, to_a = Index(np.pi, dwell_s, label="B"), Index(-np.pi, dwell_s, label="A")
    if ordering == "ABAB":
        steps = [a, Repeat([to_b, to_a], count - 1), to_b] if count > 1 else [a, to_b]
    else:  # A B | B A | A B | B A ...
        unit = [to_b, Hold(None, None, dwell_s, "B"), to_a]
        steps = [a, Repeat([*unit, Hold(None, None, dwell_s, "A")], count // 2 - 1), *unit] if count > 2 \
            else [a, *unit]
    return with_options(Sequence(NAME, _northfinding.warm_up(a, o["discard_s"]) + steps), dwell_s=dwell_s,
                        count=count, ordering=ordering, start_offset_deg=start_offset_deg, settle_s=settle_s,
                        discard_s=o["discard_s"])


def analyze(session, **options):
    """Azimuth per pair (eq. 4.6; eq. 4.3 with one level axis), their mean and the theory."""
    return _northfinding.analyze(NAME, "maytagging", OPTIONS, session, options)


def figures(result) -> dict:
    """Gyro output vs table angle and the azimuth per pair (thesis Fig. 4.6, 4.7-4.13)."""
    return procedure_figures(result.payload)
