"""Ferraris procedure on the real imucal recording (shared/data/imucal_ferraris), against imucal's result.

imucal's convention (README there): ``acc = R_a^-1 K_a^-1 (raw - b_a)``, so ``K_a R_a`` plays
the role of our ``I + M``. Tolerances are the issue's (the level the data supports): the
recording is hand-made, each position tilted by a few mrad, so the two methods can only agree
as closely as the positions' scatter lets them.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import procedures.ferraris as ferraris
from workbench.grades import load_spec
from workbench.importer import import_file
from workbench.jobs import simulate

DATA = Path("/work/shared/data/imucal_ferraris")
PROFILE = Path(__file__).parents[2] / "fixtures" / "import_profiles" / "imucal_ferraris.yaml"
pytestmark = pytest.mark.skipif(not DATA.exists(), reason="imucal recording not present")


@pytest.fixture(scope="module")
def imucal(tmp_path_factory):
    session = import_file(PROFILE, DATA / "example_ferraris_session.csv", tmp_path_factory.mktemp("imucal"))
    ref = json.loads((DATA / "imucal_result.json").read_text())
    return session, ferraris.analyze(session), ref


def test_agrees_with_imucal(imucal):
    session, result, ref = imucal
    acc, gyr = result.payload["accel"], result.payload["gyro"]
    ka_ra = np.array(ref["K_a"]) @ np.array(ref["R_a"])
    kg_rg = np.array(ref["K_g"]) @ np.array(ref["R_g"])
    assert np.abs(np.eye(3) + acc.scale_misalignment - ka_ra).max() < 2e-3
    assert np.abs(acc.bias - np.array(ref["b_a"])).max() < 0.02  # m/s^2
    assert np.abs(np.eye(3) + gyr.scale_misalignment - kg_rg).max() < 5e-3
    # gyro bias: imucal's b_g (°/s) is the mean of the six positions as ours; within 4 of our sigma
    assert np.all(np.abs(gyr.bias - np.radians(ref["b_g"])) < 4 * gyr.bias_sigma)


def test_calibrated_norms_and_turns(imucal):
    session, result, ref = imucal
    acc_model = result.calibration.model("accel")
    ka_ra = np.array(ref["K_a"]) @ np.array(ref["R_a"])
    for step in session.steps_of_kind("static"):
        raw = session.accel(step.index).mean(axis=0)
        ours = np.linalg.norm(acc_model.compensate(raw[None])[0])
        theirs = np.linalg.norm(np.linalg.solve(ka_ra, raw - np.array(ref["b_a"])))
        assert abs(ours - theirs) < 2e-3, step.label  # m/s^2 (imucal scales to 9.81, we to the site's 9.8095)
    for check in result.payload["turns"]:
        assert abs(np.degrees(check.angle) - 360.0) < 0.1, check.label


def test_goes_past_imucal(imucal):
    """Every coefficient has a finite 1-sigma; the hand-made turns are checked."""
    _, result, _ = imucal
    cal = result.calibration
    for triad, fields in (("accel", ("bias", "scale_misalignment")),
                          ("gyro", ("bias", "scale_misalignment", "g_sensitivity"))):
        for f in fields:
            sig = cal.triads[triad].sigma_of(f)
            assert np.all(np.isfinite(sig)) and np.all(sig > 0), (triad, f)
    assert 0 < result.payload["accel"].notes["position_sigma_rad"] < 0.02  # a few mrad of hand tilt
    for c in result.payload["turns"]:
        assert np.isfinite([c.closure, c.wobble_rms, c.axis_tilt, c.gravity_change, c.motion_before,
                            c.motion_after]).all()
        assert np.degrees(c.closure) < 0.1 and np.degrees(c.axis_tilt) < 1.0
    figs = ferraris.figures(result)
    assert set(figs) == {"accel_residuals", "gyro_residuals", "turn_checks"}
    assert json.loads(cal.to_json())["gyro"]["scale_misalignment_sigma"][0][0] > 0


def test_simulated_ferraris_recovers_truth():
    """On the simulated rig (exact 360° turns) the Ferraris gyro M is within 4 sigma of the truth."""
    spec = load_spec("quasi_tactical")
    session, truth = simulate(ferraris.sequence(spec, dwell_s=10.0), spec, seed=5)
    result = ferraris.analyze(session, position_sigma_deg=0.01)
    gyr = result.payload["gyro"]
    t = np.array([session.samples["temp"].mean()])
    m = truth.gyro.scale_misalignment + np.diag(truth.gyro.thermal.scale_shift(t)[0])
    assert np.all(np.abs(gyr.scale_misalignment - m) < 4 * gyr.scale_misalignment_sigma)
