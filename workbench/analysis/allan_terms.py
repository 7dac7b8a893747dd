"""Lab units and text of the IEEE 952 terms (no plotting: the CLI prints tables with it).

``TERMS`` the IEEE 952 terms in model order, ``TERM_UNITS`` per quantity (gyro / accel; a :mod:`workbench.units` name per term),
``TERM_LABELS`` the one-letter symbols (Q N B K R), :func:`term_text` one value with its label.
"""

from __future__ import annotations

import math

from workbench import units

TERMS = ("quantization", "white", "bias_instability", "rrw", "rate_ramp")

# Allan term -> its quantity in units.QUANTITIES (one vocabulary with the CLI, dashboard and certificate)
_VOCABULARY = {"quantization": "quantization", "white": "white", "bias_instability": "bias_instability",
               "rrw": "rrw", "rate_ramp": "rate_ramp"}
TERM_UNITS = {triad: {term: units.unit_of(triad, q) for term, q in _VOCABULARY.items()} for triad in ("gyro", "accel")}
TERM_LABELS = {"quantization": "Q", "white": "N", "bias_instability": "B", "rrw": "K", "rate_ramp": "R"}


def term_text(quantity: str | None, term: str, value_si: float) -> str:
    """A term's value in its lab unit with the label (``'N 0.201 °/√h'``); SI when the quantity is unknown."""
    unit = TERM_UNITS.get(quantity, {}).get(term)
    if unit is None or not math.isfinite(value_si):
        return f"{TERM_LABELS[term]} {value_si:.4g}" if math.isfinite(value_si) else f"{TERM_LABELS[term]} n/o"
    return f"{TERM_LABELS[term]} {units.to_unit(value_si, unit):.3g} {units.label(unit)}"
