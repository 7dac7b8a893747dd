"""The result protocol of a magnetometer calibration (:class:`MagCalibration`): summary lines in lab
units and a JSON ``to_dict`` (SI, not-observed figures null), on simulated fits with known truth.

Truth and simulator: ``tests/analysis/test_magnetometer.py`` (field 48 µT, dip 60°, hard iron
(8, -6, 4.5) µT, soft iron ~5 % off identity, IMU-to-mag rotation (4, -8, 10) mrad). Each point is
the mean of a 100-sample static step, so its noise is 0.3 µT / √100 = 0.03 µT per axis. Tolerance:
a printed value is within 5 of its own printed sigmas plus its display rounding (3 significant
digits: half a unit of the last digit) of the truth; with honest Gaussian sigmas a 5-sigma miss has
probability 6e-7 per figure, and the seed is fixed.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from tests.analysis.test_magnetometer import ALIGN, DIP, HARD, STEP_NOISE, F, measure, turntable
from workbench.analysis.magnetometer import MagCalibration, MagPoints, calibrate
from workbench.result import AnalysisResult

PM = re.compile(r"([xyz]) (-?[\d.]+) ± ([\d.]+) (µT|mrad)")


def _fit(tilt_deg: float, seed: int = 5) -> MagCalibration:
    """Attitude-known turntable fit: yaw steps of 30° at level (tilt 0) or at level and ±tilt about x and y."""
    att = turntable(tilt_deg, 30.0)
    m, a = measure(att, np.random.default_rng(seed), noise=STEP_NOISE)
    return calibrate(MagPoints(m, a, att, "NED"), field_norm_ut=F)


def _rounding(text: str) -> float:
    """Half a unit of the last printed digit of ``text``."""
    decimals = len(text.split(".")[1]) if "." in text else 0
    return 0.5 * 10.0 ** -decimals


@pytest.fixture(scope="module")
def tilted() -> MagCalibration:
    return _fit(30.0)


@pytest.fixture(scope="module")
def level() -> MagCalibration:
    return _fit(0.0)


def test_follows_the_result_protocol(tilted):
    assert isinstance(tilted, AnalysisResult)
    assert tilted.summary() == tilted.summary()  # no state: the same lines twice


def test_summary_lines_carry_lab_units_and_the_truth(tilted):
    lines = {line.split(":", 1)[0]: line for line in tilted.summary()}
    assert tilted.fit.method == "attitude"
    assert lines["method"].startswith("method: attitude (")
    hard = PM.findall(lines["hard iron"])
    assert [h[0] for h in hard] == ["x", "y", "z"] and {h[3] for h in hard} == {"µT"}
    for (_, v, s, _), truth in zip(hard, HARD):
        assert abs(float(v) - truth) <= 5 * float(s) + _rounding(v)
    assert re.fullmatch(r"soft iron: largest \|I\+M - I\| element [\d.]+ %, largest sigma [\d.]+ %", lines["soft iron"])
    assert lines["field norm"] == "field norm: 48 µT (given: fixes the scale of I+M)"
    dip = re.fullmatch(r"dip: ([\d.]+) ± ([\d.]+) °", lines["dip"])
    assert dip and abs(float(dip[1]) - np.degrees(DIP)) <= 5 * float(dip[2]) + _rounding(dip[1])
    rot = PM.findall(lines["IMU-to-mag rotation"])
    assert {r[3] for r in rot} == {"mrad"}
    for (_, v, s, _), truth in zip(rot, ALIGN.as_rotvec() * 1e3):  # rotation vector, mrad
        assert abs(float(v) - truth) <= 5 * float(s) + _rounding(v)
    assert re.search(r"RMS [\d.]+° \(uncalibrated [\d.]+°, plain algebraic fit [\d.]+°\)",
                     lines["heading error vs table (tilt from table)"])
    coverage = next(line for line in tilted.summary() if line.startswith("coverage"))
    assert re.fullmatch(r"coverage \d+% of the sphere, field-norm residual RMS [\d.]+ µT", coverage)


def test_to_dict_is_json_with_sigmas_where_observed(tilted):
    d = json.loads(json.dumps(tilted.to_dict(), allow_nan=False))
    fit = d["fit"]
    assert all(isinstance(v, float) for v in fit["bias_sigma_ut"])
    assert all(isinstance(v, float) for row in fit["soft_iron_sigma"] for v in row)
    assert isinstance(fit["dip_sigma_rad"], float) and isinstance(fit["declination_sigma_rad"], float)
    assert fit["dip_rad"] == pytest.approx(DIP, abs=5 * fit["dip_sigma_rad"])  # SI: rad, not °
    np.testing.assert_allclose(fit["bias_ut"], HARD, atol=5 * max(fit["bias_sigma_ut"]))


def test_level_fit_nulls_what_it_cannot_observe(level):
    assert level.fit.method == "2d"
    d = json.loads(json.dumps(level.to_dict(), allow_nan=False))  # no NaN anywhere
    fit = d["fit"]
    assert fit["bias_sigma_ut"][2] is None and all(isinstance(v, float) for v in fit["bias_sigma_ut"][:2])
    assert fit["soft_iron_sigma"][2] == [None, None, None]
    assert fit["field_norm_sigma_ut"] is None and fit["dip_rad"] is None and fit["alignment_sigma_rad"] is None
    assert d["quality"]["norm_residual_rms_ut"] is None
    lines = level.summary()
    assert "z 0 (σ not observed) µT" in next(line for line in lines if line.startswith("hard iron:"))
    assert not any(line.startswith(("dip:", "IMU-to-mag rotation:")) for line in lines)
