"""The IEEE 952 Allan model (workbench/allan_model.py) against its closed forms and against allantools.

Closed forms per term (IEEE Std 952-1997 annex C): AVAR = 3 Q²/tau², N²/tau, (2 ln2/pi) B²,
K² tau/3, R² tau²/2. The independent check: the overlapping ADEV (allantools) of seeded white
noise of density N must follow N / sqrt(tau)."""

import allantools
import numpy as np
import pytest

from workbench.allan_model import (FLICKER_AVAR, allan_deviation, allan_variance, avar_basis, dead_time_variance,
                                   window_mean_covariance)
from workbench.sim.noise import NoiseProcess


@pytest.mark.parametrize("term, value, expected", [
    ("quantization", 2e-6, lambda tau: 3 * 2e-6 ** 2 / tau ** 2),
    ("white", 3e-5, lambda tau: 3e-5 ** 2 / tau),
    ("bias_instability", 4e-6, lambda tau: 2 * np.log(2) / np.pi * 4e-6 ** 2 + 0 * tau),
    ("rrw", 5e-7, lambda tau: 5e-7 ** 2 * tau / 3),
    ("ramp", 6e-9, lambda tau: 6e-9 ** 2 * tau ** 2 / 2),
])
def test_each_term_is_its_closed_form(term, value, expected):
    tau = np.logspace(-2, 4, 13)
    np.testing.assert_allclose(allan_variance(tau, **{term: value}), expected(tau), rtol=1e-13)


def test_terms_add_and_broadcast_per_axis():
    tau = np.array([[1.0], [10.0]])  # (2, 1) against three axes
    white = np.array([1e-5, 2e-5, 3e-5])
    rrw = np.array([1e-7, 0.0, 2e-7])
    got = allan_variance(tau, white=white, rrw=rrw)
    assert got.shape == (2, 3)
    np.testing.assert_allclose(got, white ** 2 / tau + rrw ** 2 * tau / 3, rtol=1e-13)
    np.testing.assert_allclose(allan_deviation(tau, white=white, rrw=rrw), np.sqrt(got), rtol=1e-13)
    assert avar_basis(tau).shape == (2, 1, 5)


def test_flicker_floor_is_0_664_b():
    assert FLICKER_AVAR == pytest.approx(2 * np.log(2) / np.pi, rel=1e-15)
    assert np.sqrt(FLICKER_AVAR) == pytest.approx(0.6643, abs=5e-5)


def test_white_noise_adev_matches_allantools():
    # 200 000 samples at 100 Hz of density N: sample sigma N sqrt(fs). At tau = 1 s the overlapping
    # estimate has ~2000 s / 1 s terms; its relative sigma ~ 1/sqrt(2 (T/tau - 1)) = 1.6 %; 5 sigma 8 %.
    rng = np.random.default_rng(11)
    fs, n_density = 100.0, 3e-5
    y = rng.normal(0.0, n_density * np.sqrt(fs), 200_000)
    taus, adev, _, _ = allantools.oadev(y, rate=fs, data_type="freq", taus=np.array([0.1, 1.0, 10.0]))
    model = allan_deviation(taus, white=n_density)
    rel_sigma = 1.0 / np.sqrt(2.0 * (len(y) / fs / taus - 1.0))
    assert np.all(np.abs(adev / model - 1.0) < 5 * rel_sigma), adev / model


def test_dead_time_variance_is_the_allan_variance_without_a_gap():
    tau = np.array([0.5, 58.0, 1000.0])
    terms = dict(white=1e-3, bias_instability=2e-4, rrw=3e-6, quantization=1e-3, ramp=1e-8)
    np.testing.assert_allclose(dead_time_variance(tau, tau, **terms), allan_variance(tau, **terms), rtol=1e-12)


@pytest.mark.parametrize("r", [1.0, 1.5, 2.0, 4.0])
def test_dead_time_follows_barnes_b2(r):
    """Barnes (NBS TN 375, 1969) B2(r) for r = T/tau >= 1: 1 for white FM, (3r - 1)/2 for random-walk FM,
    [-2 r² ln r + (r+1)² ln(r+1) + (r-1)² ln(r-1)] / (4 ln 2) for flicker FM; white PM: 2/3 off zero gap."""
    tau = 7.0
    flicker = (-2 * r * r * np.log(r) + (r + 1) ** 2 * np.log(r + 1)
               + ((r - 1) ** 2 * np.log(r - 1) if r > 1 else 0.0)) / (4 * np.log(2))
    for terms, b2 in ((dict(white=1.0), 1.0), (dict(rrw=1.0), (3 * r - 1) / 2), (dict(bias_instability=1.0), flicker),
                      (dict(quantization=1.0), 1.0 if r == 1 else 2.0 / 3.0)):
        assert dead_time_variance(tau, r * tau, **terms) / allan_variance(tau, **terms) == pytest.approx(b2, rel=1e-12)


def test_dead_time_variance_matches_the_simulated_noise():
    """Half the mean square difference of 10-s averages 20 s apart (start to start) of the simulator's flicker
    plus random walk, 400 channels x 6 pairs far apart: 2400 nearly independent differences give the variance to
    ~sqrt(2/2400) = 2.9 %; 4 sigma 12 %. The adjacent Allan variance is 1.75x lower: the test separates them."""
    dt, tau, spacing, b, k = 1.0, 10.0, 20.0, 1e-4, 2e-5
    y = NoiseProcess(np.zeros(400), np.full(400, b), np.full(400, k), dt, 5).generate(6 * 120)
    starts = np.arange(6) * 120
    m1 = np.stack([y[s:s + 10].mean(axis=0) for s in starts])
    m2 = np.stack([y[s + 20:s + 30].mean(axis=0) for s in starts])
    measured = 0.5 * np.mean((m2 - m1) ** 2)
    expected = dead_time_variance(tau, spacing, bias_instability=b, rrw=k)
    assert expected / allan_variance(tau, bias_instability=b, rrw=k) > 1.7
    assert measured / expected == pytest.approx(1.0, abs=0.12)


def test_window_mean_covariance_of_contrasts():
    """A difference of two window means is dead_time_variance (x2); a mean minus the mean of all follows the
    direct sum over pairs; white noise alone gives N²/T on the diagonal and zero off it for disjoint windows."""
    terms = (1e-3, 2e-4, 3e-6, 1e-3)
    c = window_mean_covariance([0.0, 70.0], [58.0, 128.0], *terms)
    w = np.array([-1.0, 1.0])
    assert w @ c @ w == pytest.approx(2 * dead_time_variance(58.0, 70.0, *terms), rel=1e-12)
    white = window_mean_covariance([0.0, 10.0, 30.0], [5.0, 20.0, 31.0], white=2.0)
    np.testing.assert_allclose(white, np.diag([4.0 / 5.0, 4.0 / 10.0, 4.0 / 1.0]), atol=1e-12)
