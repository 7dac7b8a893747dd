"""Per-step extraction and checks of the turntable analyses (workbench/analysis/position_check.py).

Against closed forms (white-noise variance of a mean, the leave-one-out statistic of a mean fit)
and against the simulated rig's truth (whole revolutions of a rate step, a still hold)."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.analysis.position_check import (deleted_residual_statistics, mean_variance, motion_in_static,
                                               whole_revolution_samples)
from workbench.jobs import simulate
from workbench.sequence import Hold, Rotate, Sequence


def test_white_noise_variance_of_step_means():
    # six 10-s steps at 100 Hz of white noise sigma 0.01: W = sigma^2 / fs, var(mean_i) = W / T_i.
    # W from sample differences over 6 x 1000 samples: relative sigma sqrt(3 / 6000) = 2.2 %; 5 sigma 11 %
    rng = np.random.default_rng(5)
    fs, sigma = 100.0, 0.01
    signals = [rng.normal(0.0, sigma, (1000, 3)) + rng.normal(0, 1, 3) for _ in range(6)]
    noise = mean_variance(signals, fs)
    assert noise.white ** 2 == pytest.approx(np.full(3, sigma ** 2 / fs), rel=0.11)
    np.testing.assert_allclose(noise.variance, np.broadcast_to(noise.white ** 2 / 10.0 + noise.floor ** 2, (6, 3)))
    # the detection threshold of a floor is two standard errors of the AVAR at T/4 (2.5 s):
    # AVAR ~ W / 2.5 s, 6 steps x 3 block differences = 18 dof: 2 * AVAR * sqrt(2/18). The AVAR
    # estimate is chi-square(18) / 18 times the truth: 0.25 .. 2.5 holds it at 99.99 %
    ratio = noise.floor_limit ** 2 / (2 * sigma ** 2 / fs / 2.5 * np.sqrt(2 / 18))
    assert np.all((ratio > 0.25) & (ratio < 2.5)), ratio


def test_raising_the_floor_adds_its_variance_to_every_step_mean():
    # a unit whose bias instability the dwells are too short to show: the floor from its Allan
    # record (0.664 B) is added to the variance of every step mean, nothing else changes
    rng = np.random.default_rng(6)
    signals = [rng.normal(0.0, 0.01, (1000, 3)) for _ in range(6)]
    noise = mean_variance(signals, 100.0)
    raised = noise.with_floor(10 * noise.floor_limit.max())
    assert np.all(raised.floor == 10 * noise.floor_limit.max())
    np.testing.assert_allclose(raised.variance - noise.variance,
                               np.broadcast_to(raised.floor ** 2 - noise.floor ** 2, (6, 3)))
    np.testing.assert_array_equal(raised.white, noise.white)
    assert noise.with_floor(0.0).floor.tolist() == noise.floor.tolist()  # never lowered


def test_too_short_steps_are_refused():
    with pytest.raises(Exception, match="too short to estimate their noise"):
        mean_variance([np.zeros((7, 3))], 100.0)


def _leave_one_out_of_means(y: np.ndarray, var: np.ndarray) -> np.ndarray:
    """Closed form for designs of ones (the mean): refit without row i is the mean of the others."""
    n = len(y)
    out = np.empty(n)
    for i in range(n):
        others = np.delete(y, i, axis=0)
        m = others.mean(axis=0)
        chi2 = np.sum((others - m) ** 2 / var[0])
        scale = max(1.0, chi2 / (3 * (n - 2)))
        out[i] = np.sum((y[i] - m) ** 2 / (var[0] * n / (n - 1) * scale))
    return out


def test_deleted_residuals_match_the_closed_form_and_flag_an_outlier():
    rng = np.random.default_rng(8)
    n, var = 8, np.full((8, 3), 1e-6)
    y = rng.normal(0.0, 1e-3, (n, 3))
    y[5] += 10e-3  # 10 sigma on every axis
    designs = [np.ones((n, 1))] * 3
    stat = deleted_residual_statistics(designs, y, var)
    np.testing.assert_allclose(stat, _leave_one_out_of_means(y, var), rtol=1e-10)
    assert stat[5] > 21.1  # chi-square(3) 99.99 %
    assert np.argmax(stat) == 5
    # a row that alone observes a parameter cannot be predicted: NaN
    design = np.column_stack([np.ones(n), np.eye(n)[:, 2]])
    assert np.isnan(deleted_residual_statistics([design] * 3, y, var)[2])


@pytest.fixture(scope="module")
def rig_session():
    seq = Sequence("check", [Hold("z-down", 0.0, 6.0, "still"), Rotate("z-down", np.radians(30.0), None, 25.0, "spin")])
    session, _ = simulate(seq, "industrial_mems", seed=2)
    return session


def test_rate_step_cut_to_its_whole_revolutions(rig_session):
    spin = rig_session.steps_of_kind("rate")[0]
    df, revs = whole_revolution_samples(rig_session, spin)
    # 30 °/s for 25 s turns 750°: two whole revolutions = 24 s of samples (to one sample)
    assert revs == 2
    assert len(df) / rig_session.sample_rate_hz == pytest.approx(24.0, abs=1.5 / rig_session.sample_rate_hz)


def test_still_hold_passes_and_a_short_rate_step_is_refused(rig_session):
    still = rig_session.steps_of_kind("static")[0]
    assert motion_in_static(rig_session, still) is None
    seq = Sequence("short", [Rotate("z-down", np.radians(30.0), None, 5.0, "short")])
    short, _ = simulate(seq, "industrial_mems", seed=3)
    with pytest.raises(Exception, match=r"step 0 \(short\): turns 150.*less than one revolution"):
        whole_revolution_samples(short, short.steps[0])
