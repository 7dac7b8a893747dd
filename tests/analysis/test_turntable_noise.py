"""Noise floor of the static turntable fits (workbench.analysis.turntable_noise): closed forms."""

import numpy as np
import pytest

from workbench.allan_model import FLICKER_AVAR
from workbench.analysis.position_check import MeanNoise
from workbench.analysis.turntable_noise import bias_wander, hidden_bias_instability


def test_bias_wander_is_floor_squared_plus_between_step_variance():
    noise = MeanNoise(np.full(3, 1e-4), np.array([2e-5, 0.0, 1e-5]), np.zeros((6, 3)), np.full(3, 3e-5))
    assert bias_wander(noise, np.array([1e-10, 4e-10, 0.0])) == pytest.approx([5e-10, 4e-10, 1e-10])


def test_hidden_bias_instability_only_where_the_floor_could_hide_above_the_sigma():
    """A floor up to floor_limit can hide (F = 0 seen): B = limit / sqrt(flicker constant), where above sigma."""
    noise = MeanNoise(np.full(3, 1e-4), np.array([0.0, 0.0, 1e-5]), np.zeros((6, 3)), np.array([3e-5, 3e-5, 3e-5]))
    hidden = hidden_bias_instability(noise, np.array([1e-5, 5e-5, 1e-5]))
    assert hidden[0] == pytest.approx(3e-5 / np.sqrt(FLICKER_AVAR))
    assert np.isnan(hidden[1]) and np.isnan(hidden[2])  # limit below sigma; a floor was seen
