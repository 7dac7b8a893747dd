"""North-finding observations and axis geometry (workbench.analysis.northfinding_data), noise-free closed forms."""

import numpy as np
import pytest

from tests.analysis.test_northfinding import _body_rate, synth_session
from workbench.analysis import northfinding_data as nd


def test_circular_mean_across_the_branch_cut():
    # two directions 0.02 rad apart straddling +-pi: their mean is pi, not the arithmetic 0
    assert abs(nd.circular_mean(np.array([np.pi - 0.01, -np.pi + 0.01]))) == pytest.approx(np.pi, abs=1e-12)


def test_static_observations_are_the_step_means_after_settling():
    """Noise-free: each row is the true body rate + bias at its table angle, exactly."""
    bias = np.array([1e-4, -8e-5, 2e-3])
    s = synth_session([0.0, 90.0, 180.0], white=np.zeros(3), bias=bias)
    obs = nd.static_observations(s, settle_s=2.0)
    assert len(obs) == 3 and list(obs.step) == [0, 1, 2]
    truth = _body_rate(np.radians([0.0, 90.0, 180.0]), np.zeros(3), np.radians(102.0), np.eye(3)) + bias
    assert np.abs(obs.rate - truth).max() < 1e-15
    assert obs.duration == pytest.approx(np.full(3, 58.0), abs=0.5)  # 60 s dwell, 2 s settle, 4 Hz rows


def test_axis_geometry_of_the_level_mount():
    geom = nd.AxisGeometry.from_mount(np.eye(3), np.radians(1.0))
    assert list(geom.horizontal) == [True, True, False]
