"""The ``allan`` procedure with ``method=gmwm``: the calibration set's noise block from the GMWM fit."""

import numpy as np

from workbench import registry
from workbench.jobs import simulate


def test_gmwm_noise_block_against_truth():
    # 1200 s at the industrial MEMS grade's rate (120k samples): the white density's 1-sigma is
    # ~0.3 %; 5 % (as the IEEE 952 procedure test) also covers the flicker share at short taus.
    # The interval of every fitted white term contains the truth.
    proc = registry.procedure("allan")
    session, truth = simulate(proc.sequence(None, duration_s=1200.0, soak=False), "industrial_mems", seed=5)
    res = proc.analyze(session, method="gmwm", gmwm_model="wn+2gm", gmwm_bootstrap=10)
    cal = res.calibration.to_dict()  # schema-valid, nulls for the terms the model lacks
    for triad, term in (("gyro", "arw"), ("accel", "vrw")):
        white = truth.noise_of(triad).white
        np.testing.assert_allclose(cal["noise"][triad][term], white, rtol=0.05)
        for (lo, hi), w in zip(cal["noise"][triad][term + "_ci95"], white):
            assert lo < w < hi
        assert cal["noise"][triad]["rrw"] == [None, None, None]
    assert set(res.result["gmwm"]) == {"gyro", "accel"}
    assert any("GMWM wn+2gm" in line for line in res.summary)
