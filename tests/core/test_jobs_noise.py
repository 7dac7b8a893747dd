"""Orchestration helpers (workbench/jobs.py): noise options a campaign passes on, recorded analysis options."""

import json

import numpy as np
import pytest

from workbench.calset import CalibrationSet, TriadCalibration, Unit
from workbench.jobs import NOISE_OPTIONS, noise_options, recorded_analysis_options
from workbench.model import TriadModel
from workbench.registry import procedure
from workbench.units import factor


def _set(noise: dict) -> CalibrationSet:
    tc = TriadCalibration(TriadModel(bias=[0, 0, 0]), {})
    return CalibrationSet(Unit("SN", "m"), {"gyro": tc, "accel": tc}, noise=noise)


def test_noise_terms_in_the_option_units_unobserved_axes_at_their_upper_bound():
    b_gyro = np.array([0.5, 0.6, 0.7]) * factor("deg/h")
    allan = _set({"gyro": {"bias_instability": b_gyro.tolist()},
                  "accel": {"bias_instability": [1e-5, None, 2e-5],
                            "bias_instability_ci95": [[0.5e-5, 2e-5], [0.0, 3e-5], [1e-5, 4e-5]]}})
    proc = procedure("multiposition")
    declared = {o.name for o in proc.OPTIONS}
    got = noise_options(proc, [allan])
    assert set(got) == set(NOISE_OPTIONS) & declared - {k for k in NOISE_OPTIONS if "rrw" in k}
    np.testing.assert_allclose(got["gyro_bias_instability_deg_h"], [0.5, 0.6, 0.7], rtol=1e-12)
    # accel y not observed: the upper end of its 95 % interval, in mg
    np.testing.assert_allclose(got["accel_bias_instability_mg"], np.array([1e-5, 3e-5, 2e-5]) / factor("mg"),
                               rtol=1e-12)


def test_the_first_set_with_the_term_wins_and_undeclared_options_are_not_passed():
    first = _set({"gyro": {"bias_instability": [1e-6] * 3}})
    second = _set({"gyro": {"bias_instability": [9e-6] * 3}})
    got = noise_options(procedure("multiposition"), [_set({}), first, second])
    assert got["gyro_bias_instability_deg_h"] == pytest.approx([1e-6 / factor("deg/h")] * 3)
    assert noise_options(procedure("carousel"), [first]) == {}  # carousel declares none of them


def test_recorded_analysis_options(tmp_path):
    (tmp_path / "session.json").write_text(json.dumps({"analysis_options": {"earth_rate": "ignore"}}))
    assert recorded_analysis_options(tmp_path) == {"earth_rate": "ignore"}
    assert recorded_analysis_options(tmp_path / "missing") == {}
