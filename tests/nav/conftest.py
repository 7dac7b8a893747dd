"""Fixtures of the navigation tests: calibration sets made from a simulated unit's truth.

The nav tests must not depend on the turntable procedures, so a "calibrated" set is the
unit's true error model perturbed by estimation errors of a realistic lab calibration
(1-sigma, drawn with a fixed seed): gyro bias 1 °/h, accel bias 0.05 mg, scale factor and
misalignment 100 ppm / 0.1 mrad, mag hard iron 0.1 µT, soft iron 0.2 %. Nonlinearity,
g-sensitivity and thermal terms are taken as true. The noise block holds the true terms.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from workbench.calset import CalibrationSet, TriadCalibration, Unit
from workbench.units import G0, factor

CAL_ERRORS = {  # triad: (bias 1-sigma SI, scale/misalignment 1-sigma)
    "gyro": (1.0 * factor("deg/h"), 100e-6),
    "accel": (0.05e-3 * G0, 100e-6),
    "mag": (0.1, 2e-3),
}


def calibration_from_truth(truth, seed: int = 7, errors: dict = CAL_ERRORS,
                           serial: str | None = None) -> CalibrationSet:
    """A calibration set: ``truth``'s models perturbed by ``errors`` (see the module docstring)."""
    rng = np.random.default_rng(seed)
    triads = {}
    for name in truth.triads:
        model = truth.model_of(name)
        sb, sm = errors[name]
        est = replace(model, bias=model.bias + rng.normal(0.0, sb, 3),
                      scale_misalignment=model.scale_misalignment + rng.normal(0.0, sm, (3, 3)))
        sigma = {"bias": np.full(3, sb), "scale_misalignment": np.full((3, 3), sm)}
        triads[name] = TriadCalibration(est, sigma, field_norm_ut=48.0 if name == "mag" else None,
                                        field_norm_ut_sigma=0.1 if name == "mag" else None)
    noise = {}
    for name, white in (("gyro", "arw"), ("accel", "vrw")):
        n = truth.noise_of(name)
        noise[name] = {white: n.white.tolist(), "bias_instability": n.bias_instability.tolist(),
                       "rrw": n.rrw.tolist()}
    return CalibrationSet(Unit(serial or truth.serial, truth.model), triads, noise)


@pytest.fixture
def make_calibration():
    return calibration_from_truth
