"""Multi-position procedure: position sets, options, analysis on the simulated rig, outputs."""

from __future__ import annotations

import json

import numpy as np
import pytest

import procedures.multiposition as multiposition
from workbench.errors import ProcedureError
from workbench.grades import load_spec
from workbench.registry import campaign_procedures
from workbench.sequence import mount_matrix
from workbench.jobs import simulate


@pytest.fixture(scope="module")
def spec():
    return load_spec("industrial_mems")


@pytest.mark.parametrize("n", [6, 12, 18, 24])
def test_position_sets(spec, n):
    seq = multiposition.sequence(spec, positions=n, dwell_s=5.0)
    steps = seq.expand()
    assert len(steps) == n and all(s.kind == "static" for s in steps)
    up = np.array([mount_matrix(s.mount).T @ [0.0, 0.0, -1.0] for s in steps])  # body direction of 'up'
    assert np.allclose(np.linalg.norm(up, axis=1), 1.0)
    levels = {round(float(v), 3) for v in np.abs(up).ravel()}
    # off-axis inputs (0.707 g) only in the 12/18/24 sets; 18 and 24 also have 0 and 1 g
    assert levels == {0.0, 1.0} if n == 6 else levels >= {0.0, 0.707}
    if n in (18, 24):
        assert 1.0 in levels
    if n != 24:  # gravity directions are distinct
        assert len({tuple(np.round(u, 6)) for u in up}) == n


def test_bad_options(spec):
    with pytest.raises(ProcedureError, match="positions=7"):
        multiposition.sequence(spec, positions=7)
    with pytest.raises(ProcedureError, match="unknown option"):
        multiposition.sequence(spec, dwell=3)


def test_campaign_order():
    names = [m.NAME for m in campaign_procedures({"accel", "gyro"})]
    assert names.index("multiposition") < names.index("rate")
    assert "ferraris" not in names


def test_analyze_outputs(spec):
    session, _ = simulate(multiposition.sequence(spec, positions=6, dwell_s=10.0), spec, seed=2)
    result = multiposition.analyze(session)
    cal = result.calibration
    assert set(cal.triads) == {"accel", "gyro"}
    d = json.loads(cal.to_json())  # validates against the schema
    assert d["accel"]["nonlinearity_sigma"] == [None, None, None]  # 6 positions cannot observe it
    assert all(v is not None for row in d["gyro"]["g_sensitivity_sigma"] for v in row)
    assert d["gyro"]["scale_misalignment_sigma"][0][0] is None  # static positions do not observe M
    assert any("accel max residual" in line and "mg" in line for line in result.summary)
    assert any("Earth rate" in line for line in result.summary)
    figs = multiposition.figures(result)
    assert set(figs) == {"accel_residuals", "gyro_residuals"}


@pytest.mark.parametrize("value", ["abc", [8, 8], -3.0])
def test_bad_bias_instability_option_names_it(spec, value):
    session, _ = simulate(multiposition.sequence(spec, positions=6, dwell_s=2.0), spec, seed=4)
    with pytest.raises(ProcedureError, match=r"multiposition: gyro_bias_instability_deg_h=.* \(deg/h\)"):
        multiposition.analyze(session, gyro_bias_instability_deg_h=value)
