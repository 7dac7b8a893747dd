"""Lab-unit text of the IEEE 952 terms (workbench/analysis/allan_terms.py) against hand-written
unit conversions (deg = pi/180 rad, h = 3600 s, sqrt(h) = 60 sqrt(s), ug = 9.80665e-6 m/s^2).

The text carries 3 significant digits, so the printed number must equal the expected lab value
to half a unit of its third digit (relative 5e-3 of a value in [1, 10)).
"""

import math

import pytest

from workbench.analysis.allan_terms import TERM_LABELS, term_text

DEG = math.pi / 180.0
UG = 9.80665e-6
# (quantity, term, SI value, lab value it is, unit label)
CASES = [
    ("gyro", "white", 2.5 * DEG / 60.0, 2.5, "°/√h"),  # ARW: deg/sqrt(h) -> rad/sqrt(s)
    ("gyro", "bias_instability", 3.5 * DEG / 3600.0, 3.5, "°/h"),
    ("gyro", "rrw", 4.5 * DEG / 3600.0 / 60.0, 4.5, None),  # deg/h/sqrt(h) -> rad/s/sqrt(s)
    ("gyro", "rate_ramp", 5.5 * DEG / 3600.0 ** 2, 5.5, None),  # deg/h/h -> rad/s^2
    ("gyro", "quantization", 6.5 * DEG / 3600.0, 6.5, None),  # arcsec -> rad
    ("accel", "white", 7.5 * UG, 7.5, "µg/√Hz"),  # VRW: ug/sqrt(Hz) -> m/s^2/sqrt(Hz)
    ("accel", "bias_instability", 8.5 * UG, 8.5, "µg"),
    ("accel", "rrw", 1.5 * UG / 60.0, 1.5, None),  # ug/sqrt(h) -> m/s^2/sqrt(s)
    ("accel", "rate_ramp", 2.25 * UG / 3600.0, 2.25, None),  # ug/h -> m/s^3
    ("accel", "quantization", 3.25e-3, 3.25, None),  # mm/s -> m/s
]


@pytest.mark.parametrize("quantity,term,si,lab,unit", CASES)
def test_term_text_prints_the_lab_value_with_the_term_letter(quantity, term, si, lab, unit):
    text = term_text(quantity, term, si)
    letter, number, label = text.split(" ", 2)
    assert letter == TERM_LABELS[term]
    assert float(number) == pytest.approx(lab, rel=5e-3), text
    if unit is not None:
        assert label == unit


def test_unknown_quantity_prints_si_and_unobserved_prints_n_o():
    assert term_text(None, "white", 0.000123) == "N 0.000123"
    assert term_text("gyro", "rrw", float("nan")) == "K n/o"
    assert term_text(None, "rate_ramp", float("inf")) == "R n/o"
