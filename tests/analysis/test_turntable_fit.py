"""Turntable fit machinery (workbench.analysis.turntable_fit): the result type and the site check."""

from types import SimpleNamespace

import numpy as np
import pytest

from workbench.analysis.turntable_fit import TriadFit, check_site
from workbench.errors import AnalysisError


def test_triad_fit_to_calibration_carries_estimates_and_sigmas():
    nan3, nan33 = np.full(3, np.nan), np.full((3, 3), np.nan)
    m = np.array([[1e-3, 2e-4, 0.0], [0.0, -5e-4, 1e-4], [0.0, 0.0, 2e-3]])
    fit = TriadFit("accel", np.array([0.01, -0.02, 0.03]), m, np.zeros(3), None,
                   np.array([1e-4, 1e-4, 2e-4]), nan33, nan3, None)
    cal = fit.to_calibration()
    assert cal.model.bias == pytest.approx([0.01, -0.02, 0.03]) and np.allclose(cal.model.scale_misalignment, m)
    assert cal.sigma_of("bias") == pytest.approx([1e-4, 1e-4, 2e-4])
    assert np.isnan(cal.sigma_of("scale_misalignment")).all()  # not observed stays not observed


def test_a_site_without_latitude_is_refused():
    with pytest.raises(AnalysisError, match="s1: site.latitude_deg is missing"):
        check_site(SimpleNamespace(name="s1", site=SimpleNamespace(latitude_deg=None)))
