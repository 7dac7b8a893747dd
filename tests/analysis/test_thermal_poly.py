"""Thermal polynomials (workbench.analysis.thermal_poly): an exact quadratic is recovered."""

import numpy as np
import pytest

from workbench.analysis.thermal_poly import MAX_ORDER, fit_thermal_poly


def test_noise_free_quadratic_gives_order_2_and_its_coefficients():
    temps = np.array([-10.0, 0.0, 10.0, 20.0, 30.0, 40.0, 50.0])
    true = np.array([[1e-3, 2e-5, 3e-7], [-2e-3, -1e-5, 0.0], [5e-4, 0.0, -4e-7]])  # (3 axes, order 0..2)
    dt = temps - 25.0
    y = np.column_stack([true[a, 0] + true[a, 1] * dt + true[a, 2] * dt ** 2 for a in range(3)])
    sigma = 1e-9  # the measurement 1-sigma the fit is told: the coefficients must agree to ~sigma
    fit = fit_thermal_poly(temps, y, np.full(y.shape, sigma), t_ref_c=25.0, hysteresis="off")
    assert list(fit.orders) == [2, 1, 2]  # axis y has no quadratic term: the lowest adequate order
    assert fit.cv_rms.shape == (MAX_ORDER + 1, 3)
    got = fit.coeffs[:, :3]
    assert np.abs(got - true).max() < 1e-8
    assert fit.predict(np.array([25.0]))[0] == pytest.approx(true[:, 0], abs=1e-8)
