"""Honesty of the Ferraris accelerometer sigmas on MEMS grades with 10-s dwells (simulated rig).

Six 10-s dwells cannot show a MEMS accelerometer's bias instability, which moves the bias away
from its turn-on value (the truth) by several times the white noise of a dwell mean: before,
the bias z-scores over 10 seeds had rms 3.3 (industrial MEMS) and 3.9 (consumer 9-axis), up to
9.8. Tolerance as tests/analysis/test_turntable_sigma.py: 10 seeds x 3 axes honest z-scores
have sum z^2 ~ chi-square(30); the test accepts its 0.5 % .. 99.5 % band (13.8 .. 53.7).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

import procedures.ferraris as ferraris
from workbench import units
from workbench.errors import ProcedureError
from workbench.grades import load_spec
from workbench.jobs import simulate


def _bias_truth(model, session) -> np.ndarray:
    return model.bias + model.thermal.bias_shift(np.array([session.samples["temp"].mean()]))[0]


@pytest.mark.parametrize("grade", ["industrial_mems", "consumer_9axis"])
def test_accel_bias_sigma_honest_without_the_units_bias_instability(grade):
    spec = load_spec(grade)
    z = []
    for seed in range(300, 310):
        session, truth = simulate(ferraris.sequence(spec, dwell_s=10.0), spec, seed=seed)
        res = ferraris.analyze(session)
        acc = res.payload["accel"]
        z.append((acc.bias - _bias_truth(truth.accel, session)) / acc.bias_sigma)
        if np.isfinite(acc.notes.get("bias_instability_assumed", [np.nan])).any():
            assert "could hide" in acc.notes["bias_instability_source"]
    z = np.concatenate(z)
    assert chi2.ppf(0.005, z.size) < np.sum(z**2) < chi2.isf(0.005, z.size), np.sqrt(np.mean(z**2))


def test_accepts_the_noise_options_of_multiposition():
    """The warning of a short-dwell fit advises the unit's bias instability: ferraris takes it."""
    spec = load_spec("industrial_mems")
    session, truth = simulate(ferraris.sequence(spec, dwell_s=10.0), spec, seed=301)
    b_acc = float(spec.accel.noise.bias_instability[0] / units.factor("mg"))
    b_gyr = float(spec.gyro.noise.bias_instability[0] / units.factor("deg/h"))
    given = ferraris.analyze(session, accel_bias_instability_mg=b_acc, gyro_bias_instability_deg_h=[b_gyr] * 3)
    acc = given.payload["accel"]
    assert "bias_instability_assumed" not in acc.notes
    assert not any("would not show" in w for w in given.warnings)
    # the floor 0.664 B is in the bias sigma
    assert np.all(acc.bias_sigma >= 0.664 * b_acc * units.factor("mg"))
    with pytest.raises(ProcedureError, match="accel_bias_instability_mg"):
        ferraris.analyze(session, accel_bias_instability_mg="x")
    with pytest.raises(ProcedureError, match="gyro_nonlinearity_ppm_per_dps"):
        ferraris.analyze(session, gyro_nonlinearity_ppm_per_dps=-1)
