"""Rate procedure: the sequence (whole revolutions, CW and CCW, rates up to the range) and its analysis."""

from __future__ import annotations

import numpy as np
import pytest

import procedures.rate as rate
from workbench.grades import load_spec
from workbench.jobs import simulate


@pytest.fixture(scope="module")
def spec():
    return load_spec("industrial_mems")


def test_sequence_whole_revolutions(spec):
    seq = rate.sequence(spec, rates_fs=[0.1, 0.5, 1.5], max_rate_dps=500.0, min_duration_s=3.0)
    steps = seq.expand()
    rates = sorted({round(abs(np.degrees(s.table_rate)), 6) for s in steps})
    assert rates == [45.0, 225.0, 500.0]  # 1.5 x 450 °/s is capped at the rig's 500 °/s
    assert len(steps) == 3 * 3 * 2
    for s in steps:
        revs = abs(s.table_rate) * s.duration_s / (2 * np.pi)
        assert abs(revs - round(revs)) < 1e-9 and revs >= 1 and s.duration_s >= 3.0 - 1e-9
    assert seq.options["full_scale_dps"] == pytest.approx(450.0)


def test_two_rates_warn_nonlinearity(spec):
    seq = rate.sequence(spec, rates_fs=[0.2, 0.8], min_duration_s=2.0)
    session, _ = simulate(seq, spec, seed=4)
    result = rate.analyze(session)
    fit = result.payload["gyro"]
    assert any("nonlinearity" in w and "not observable" in w for w in result.warnings)
    assert np.isnan(fit.nonlinearity_sigma).all() and np.isfinite(fit.asymmetry_sigma).all()
    assert np.isnan(result.calibration.triads["gyro"].sigma_of("bias")).all()  # 3 "up" mounts: bias vs G
    assert any("% of full scale" in line for line in result.summary)
    figs = rate.figures(result)
    assert set(figs) == {"gyro_residuals", "rate_tracking", "scale_factor_vs_rate"}
