"""The numpy-only chi-squared quantile against scipy.stats.chi2.ppf (the independent reference)."""

import numpy as np
import pytest
from scipy.stats import chi2

from workbench.analysis.chi2 import chi2_ppf, gamma_p


def test_ppf_matches_scipy_over_the_edf_range():
    # EDF of the stability statistics run from ~0.1 (a few long-tau points) to ~1e7 (tau0 of a
    # long record); both sides of the interval and Stable32's 1-sigma level
    q = np.array([1e-4, 0.0025, 0.025, 0.05, 0.1587, 0.5, 0.8413, 0.95, 0.975, 0.9975, 0.9999])
    dof = np.concatenate([np.geomspace(0.05, 1e7, 80), [1.0, 2.0, 3.0, 199.9, 200.0, 200.1]])
    qq, dd = np.meshgrid(q, dof)
    got = chi2_ppf(qq, dd)
    assert np.max(np.abs(got / chi2.ppf(qq, dd) - 1)) < 1e-10


def test_gamma_p_matches_scipy():
    from scipy.special import gammainc

    for a in (0.05, 0.5, 1.0, 7.3, 99.0, 101.0, 5e3, 2e6):
        for x in a * np.array([1e-3, 0.3, 0.9, 1.0, 1.1, 3.0]):
            # relative 2e-9 (24-point quadrature at a = 2e6) where P matters to a quantile of q in
            # [1e-4, 1 - 1e-4]; deep tails absolute
            assert gamma_p(a, x) == pytest.approx(gammainc(a, x), rel=2e-9, abs=1e-16)


def test_invalid_arguments_give_nan():
    out = chi2_ppf(np.array([0.0, 1.0, 0.5, 0.5]), np.array([3.0, 3.0, 0.0, np.nan]))
    assert np.all(np.isnan(out))
    assert float(chi2_ppf(0.975, 10)) == pytest.approx(chi2.ppf(0.975, 10), rel=1e-12)
