"""The IEEE 952 Allan model (workbench/allan_model.py) against its closed forms and against allantools.

Closed forms per term (IEEE Std 952-1997 annex C): AVAR = 3 Q²/tau², N²/tau, (2 ln2/pi) B²,
K² tau/3, R² tau²/2. The independent check: the overlapping ADEV (allantools) of seeded white
noise of density N must follow N / sqrt(tau)."""

import allantools
import numpy as np
import pytest

from workbench.allan_model import FLICKER_AVAR, allan_deviation, allan_variance, avar_basis


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
