"""The bias instability as a Gauss-Markov state (workbench.nav.bias_model) against independent references."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from workbench.allan_model import allan_deviation
from workbench.grades import load_spec
from workbench.nav.bias_model import (GM_PEAK_ADEV, GM_PEAK_X, allan_minimum_tau, gauss_markov_avar,
                                      gauss_markov_from_allan)


def _gauss_markov(n: int, dt: float, sigma: float, tau: float, seed: int) -> np.ndarray:
    """A first-order Gauss-Markov series (exact AR(1) discretisation), started in its steady state."""
    rng = np.random.default_rng(seed)
    a = np.exp(-dt / tau)
    w = rng.standard_normal(n) * sigma * np.sqrt(1.0 - a * a)
    w[0] = rng.standard_normal() * sigma
    return lfilter([1.0], [1.0, -a], w)


def test_gauss_markov_avar_matches_allantools_on_a_simulated_process():
    # 2e6 samples at 1 s, T = 100 s: overlapping ADEV at tau = 10..1000 s has ~ sqrt(T_rec / tau)-limited EDF,
    # >= 2000 independent tau-blocks, so a relative ADEV spread <= 1 / sqrt(2 * 2000 / 3) ~ 2.7 %; 4 sigma: 11 %
    allantools = pytest.importorskip("allantools")
    sigma, tau = 2.0, 100.0
    x = _gauss_markov(2_000_000, 1.0, sigma, tau, seed=3)
    taus = np.array([10.0, 50.0, 189.0, 500.0, 1000.0])
    t_out, dev, _, _ = allantools.oadev(x, rate=1.0, data_type="freq", taus=taus)
    np.testing.assert_allclose(dev, np.sqrt(gauss_markov_avar(t_out, sigma, tau)), rtol=0.11)


def test_peak_and_limits_of_the_gauss_markov_allan_deviation():
    # closed-form limits: a rate random walk 2 sigma^2 tau / (3 T) well below T, white 2 sigma^2 T / tau well above
    assert gauss_markov_avar(1e-3, 1.0, 1.0) == pytest.approx(2e-3 / 3, rel=1e-3)
    assert gauss_markov_avar(1e4, 1.0, 1.0) == pytest.approx(2e-4, rel=1e-3)
    assert GM_PEAK_X == pytest.approx(1.893, abs=1e-3) and GM_PEAK_ADEV == pytest.approx(0.6174, abs=1e-4)


def test_mapping_puts_the_peak_on_the_flicker_floor_at_the_allan_minimum():
    n = load_spec("tactical_low_noise").specs["gyro"].noise
    sigma, tau = gauss_markov_from_allan(n.white, n.bias_instability, n.rrw, n.quantization)
    tau_min = allan_minimum_tau(n.white, n.bias_instability, n.rrw, n.quantization)
    # white + flicker + rate random walk only: the minimum is at sqrt(3) N / K (grid of 200 points per decade)
    np.testing.assert_allclose(tau_min, np.sqrt(3.0) * n.white / n.rrw, rtol=0.012)
    assert np.all(allan_deviation(tau_min, n.white, n.bias_instability, n.rrw)
                  <= allan_deviation(tau_min * np.array([[0.9], [1.1]]), n.white, n.bias_instability, n.rrw))
    np.testing.assert_allclose(np.sqrt(gauss_markov_avar(tau_min, sigma, tau)),
                               allan_deviation(tau_min, bias_instability=n.bias_instability), rtol=1e-9)
    # nothing observed after the floor: the cap; no bias instability: no state
    assert allan_minimum_tau(1e-5, 1e-6) == pytest.approx(1e5)
    assert gauss_markov_from_allan(1e-5, np.nan)[0] == 0.0
