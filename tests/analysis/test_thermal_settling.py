"""Thermal settling (workbench.analysis.thermal_settling) against a closed form."""

import numpy as np
import pytest

from workbench.analysis.thermal_settling import settling, windowed_slope


def test_first_order_approach_settles_when_its_slope_falls_below_the_tolerance():
    """T = 25 + 10 exp(-t/600): |dT/dt| = 1 °C/min exp(-t/600) < 0.05 °C/min after 600 ln 20 = 1797 s.

    The slope is fitted over a trailing 120 s window of 12 s bins, so detection lags by about
    half the window (60 s) plus a bin: the bound below.
    """
    t = np.arange(0.0, 4000.0, 1.0)
    temp = 25.0 + 10.0 * np.exp(-t / 600.0)
    s = settling(t, temp, tol_c_per_min=0.05, window_s=120.0)
    assert s.settled and 600 * np.log(20) <= s.t_settled <= 600 * np.log(20) + 72.0
    assert s.final_rate_c_per_min == pytest.approx(-np.exp(-4000 / 600), rel=0.2)


def test_windowed_slope_of_a_ramp_is_the_ramp_rate():
    t = np.arange(0.0, 600.0, 0.5)
    tb, slope = windowed_slope(t, 20.0 + 0.01 * t, 60.0)
    assert np.isnan(slope[0]) and np.nanmax(np.abs(slope - 0.01)) < 1e-9  # °C/s, exact for a line
    assert len(tb) == len(slope)
