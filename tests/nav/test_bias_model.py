"""The bias instability as a Gauss-Markov state (workbench.nav.bias_model) against independent references."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from workbench.allan_model import allan_deviation
from workbench.grades import load_spec
from workbench.nav.bias_model import (GM_PEAK_ADEV, GM_PEAK_X, allan_minimum_tau, flicker_ladder, gauss_markov_avar,
                                      gauss_markov_from_allan, ladder_weights)


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


@pytest.mark.parametrize("rungs, ripple", [(2, 0.03), (3, 0.02), (4, 0.02)])
def test_ladder_allan_deviation_is_the_flicker_floor_over_its_span(rungs, ripple):
    # the summed Allan variance of the rungs against allan_model's flicker term 0.664 B over the decades the
    # rungs span (their peaks, tau_min 10^(+-(L-1)/2)), on a grid independent of the fit's; first-order processes
    # a decade apart ripple: measured -2.4/+0.6 % (2 rungs), -1.4/+0.7 % (3), -1.8/+1.0 % (4)
    n = load_spec("tactical_low_noise").specs["gyro"].noise
    sigma, tau = flicker_ladder(n.white, n.bias_instability, n.rrw, n.quantization, rungs=rungs)
    tau_min = allan_minimum_tau(n.white, n.bias_instability, n.rrw, n.quantization)
    assert sigma.shape == tau.shape == (rungs, 3)
    span = (rungs - 1) / 2.0
    taus = tau_min[0] * np.logspace(-span, span, 37)
    ladder = np.sqrt(sum(gauss_markov_avar(taus, sigma[k, 0], tau[k, 0]) for k in range(rungs)))
    flicker = allan_deviation(taus, bias_instability=n.bias_instability[0])
    np.testing.assert_allclose(ladder, flicker, rtol=ripple)
    # one decade beyond the span it falls away (a finite ladder is not flicker for ever)
    assert np.sqrt(sum(gauss_markov_avar(taus[0] / 30, sigma[k, 0], tau[k, 0]) for k in range(rungs))) \
        < 0.6 * flicker[0]


def test_one_rung_ladder_is_the_single_gauss_markov_state():
    n = load_spec("navigation_grade").specs["gyro"].noise
    np.testing.assert_allclose(np.vstack(flicker_ladder(n.white, n.bias_instability, n.rrw, rungs=1)),
                               np.vstack(gauss_markov_from_allan(n.white, n.bias_instability, n.rrw)), rtol=1e-12)
    assert np.all(flicker_ladder(1e-5, np.full(3, np.nan))[0] == 0.0)  # not observed: no states
    with pytest.raises(ValueError, match="rungs=0"):
        ladder_weights(0)


def test_sampled_ladder_allan_deviation_matches_the_flicker_floor_with_allantools():
    # the three rungs for tau_min = 18.93 s (T = 1, 10, 100 s) drawn as exact AR(1) series and summed; allantools'
    # overlapping ADEV at 2-200 s of 1e6 samples at 0.1 s: >= 500 independent tau-blocks, relative spread
    # <= 1 / sqrt(2 * 500 / 3) ~ 5.5 %, and the ladder's own ripple 1.4 %: 4 sigma + ripple, 24 %
    allantools = pytest.importorskip("allantools")
    b = 1.0
    x_k, w_k = ladder_weights(3)
    x = sum(_gauss_markov(1_000_000, 0.1, b * np.sqrt(w), xk * 10.0 * GM_PEAK_X, seed=10 + k)
            for k, (xk, w) in enumerate(zip(x_k, w_k)))
    taus = np.array([2.0, 6.0, 19.0, 60.0, 190.0])
    t_out, dev, _, _ = allantools.oadev(x, rate=10.0, data_type="freq", taus=taus)
    np.testing.assert_allclose(dev, allan_deviation(t_out, bias_instability=b), rtol=0.24)
