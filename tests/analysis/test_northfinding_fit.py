"""North-finding estimators (workbench.analysis.northfinding_fit): noise-free closed forms."""

import numpy as np
import pytest

from tests.analysis.test_northfinding import LAT, OMEGA_N, synth_session
from workbench.analysis import northfinding_data as nd
from workbench.analysis import northfinding_fit as nf


def test_harmonic_of_a_full_turn_recovers_azimuth_and_amplitude():
    """Eight noise-free positions round the turn: the sinusoid's phase is the azimuth, its amplitude Omega_N."""
    s = synth_session(list(range(0, 360, 45)), white=np.zeros(3), az0_deg=-65.0)
    obs = nd.static_observations(s, settle_s=2.0)
    fit = nf.fit_harmonic(obs, nd.AxisGeometry.from_mount(np.eye(3), np.radians(1.0)), LAT)
    assert fit.azimuth == pytest.approx(np.radians(-65.0), abs=1e-9)
    assert fit.amplitude == pytest.approx(OMEGA_N, rel=1e-9)


def test_repeatability_is_the_largest_distance_from_the_mean():
    rep, dist = nf.repeatability(np.array([0.1, 0.3, 0.2]))
    assert rep == pytest.approx(0.1, abs=1e-12) and dist == pytest.approx([-0.1, 0.1, 0.0], abs=1e-12)
