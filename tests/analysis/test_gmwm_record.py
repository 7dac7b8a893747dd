"""GMWM of a whole record (workbench/analysis/gmwm_record.py) on a simulated gyro triad of known
white noise N and rate random walk K (plain numpy simulation: white samples of std N sqrt(rate),
the random walk's increments of std K sqrt(dt)).

Tolerances: the truth within 4 of the fit's own sigmas (sigma = 95 % half-width / 1.96); the white
term's sigma at least 0.6 x the Cramer-Rao bound of a white record, N / sqrt(2 n) (no estimator
does better; the sigma itself comes from 50 bootstrap records, relative error ~ 1/sqrt(2 x 50) =
10 %: 4 of those), and at most 4x it (an interval too wide to be of use fails).
"""

import numpy as np
import pytest

from workbench import units
from workbench.analysis.gmwm_record import analyze_gmwm
from workbench.errors import AnalysisError

RATE, N_SAMPLES = 100.0, 1 << 15
N_TRUE = np.radians(0.2) / 60.0  # rad/sqrt(s): 0.2 °/√h
K_TRUE = np.sqrt(3.0) * N_TRUE / 10.0  # rad/s/sqrt(s): ADEV of white and RRW cross at tau = 10 s
COLUMNS = ("gx", "gy", "gz")


def _record(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    white = N_TRUE * np.sqrt(RATE) * rng.standard_normal((N_SAMPLES, 3))
    walk = np.cumsum(K_TRUE / np.sqrt(RATE) * rng.standard_normal((N_SAMPLES, 3)), axis=0)
    return white + walk


@pytest.fixture(scope="module")
def analysis():
    return analyze_gmwm(_record(1), RATE, COLUMNS, "gyro", model="wn+rw", bootstrap=50, seed=3)


def test_terms_hold_the_truth_within_their_sigmas(analysis):
    crb = N_TRUE / np.sqrt(2 * N_SAMPLES)
    for fit in analysis.fits:
        for term, truth in (("white", N_TRUE), ("rrw", K_TRUE)):
            value, lo, hi = fit.terms[term]
            sigma = (hi - lo) / (2 * 1.96)
            assert abs(value - truth) < 4 * sigma, (fit.column, term, value, truth, sigma)
        sigma_n = (fit.terms["white"][2] - fit.terms["white"][1]) / (2 * 1.96)
        assert 0.6 * crb < sigma_n < 4 * crb, (fit.column, sigma_n / crb)


def test_noise_block_has_the_calibration_set_layout(analysis):
    block = analysis.noise_block()
    assert block["arw"] == [f.terms["white"][0] for f in analysis.fits]
    assert block["rrw_ci95"] == [list(f.terms["rrw"][1:]) for f in analysis.fits]
    assert block["bias_instability"] == [None, None, None]  # no flicker or Gauss-Markov term in wn+rw
    assert block["quantization"] == [None] * 3 and block["rate_ramp"] == [None] * 3
    with pytest.raises(ValueError, match="triad"):
        analyze_gmwm(_record(1)[:, :1], RATE, ("gx",), "gyro", model="wn", bootstrap=50).noise_block()


def test_summary_prints_lab_units(analysis):
    lines = analysis.summary()
    assert len(lines) == 3 and lines[0].startswith("gx (GMWM wn+rw): N ")
    value = float(lines[0].split("N ", 1)[1].split()[0])
    assert value == pytest.approx(units.to_unit(analysis.fits[0].terms["white"][0], "deg/sqrt(h)"), rel=5e-3)
    assert value == pytest.approx(0.2, rel=0.03)  # 0.2 °/√h; 4 sigma of 0.4 % plus 3-digit rounding


def test_gaps_error_names_the_column_or_the_longest_run_is_fitted():
    y = _record(2)
    y[20_000:20_010, 1] = np.nan
    with pytest.raises(AnalysisError, match="column gy"):
        analyze_gmwm(y, RATE, COLUMNS, "gyro", model="wn", bootstrap=50)
    a = analyze_gmwm(y, RATE, COLUMNS, "gyro", model="wn", bootstrap=50, gap_policy="longest")
    b = analyze_gmwm(y[:20_000], RATE, COLUMNS, "gyro", model="wn", bootstrap=50)
    for fa, fb in zip(a.fits, b.fits):
        assert fa.terms["white"][0] == pytest.approx(fb.terms["white"][0], rel=1e-12)
    assert a.warnings
