"""EDF and bounds of workbench/analysis/stability_ci.py against independent references.

White PM: the phase points are independent, so each finite-difference statistic is a quadratic
form Q = d'd of Gaussian differences d = A x, cov(d) = C = A A'. Its equivalent degrees of freedom
2 E[Q]^2 / var Q = tr(C)^2 / tr(C^2) are exact (a plain numpy reference, built here from the
definition of each statistic); Greenhall & Riley's white-PM result is exact too, so the tolerance is
float rounding (1e-9 relative). Other noise types: allantools' own edf_greenhall (independent code
of the same paper) on records short enough that neither side rescales the sum (J <= 100), where
both evaluate the same finite sum: 1e-6 relative. Bounds: scipy's chi-squared quantiles.
"""

from math import comb

import allantools
import numpy as np
import pytest
from scipy import stats as sps

from workbench.analysis.stability import stability
from workbench.analysis.stability_ci import edf_of, edf_simple, intervals

SPEC = {"adev": (2, False, False), "oadev": (2, True, False), "mdev": (2, True, True),
        "hdev": (3, False, False), "ohdev": (3, True, False)}  # d, overlapping, modified


def _difference_rows(n_phase: int, m: int, d: int, overlapping: bool, modified: bool) -> np.ndarray:
    """Rows: the d-th differences at lag m of the phase (modified: averaged over m shifts), as maps of x."""
    coef = [(-1) ** (d - k) * comb(d, k) for k in range(d + 1)]
    span = d * m + (m - 1 if modified else 0)
    starts = np.arange(0, n_phase - span, 1 if overlapping else m)
    a = np.zeros((len(starts), n_phase))
    shifts = range(m) if modified else range(1)
    for r, s in enumerate(starts):
        for j in shifts:
            for k, c in enumerate(coef):
                a[r, s + j + k * m] += c / len(shifts)
    return a


def _exact_edf_white_pm(n_phase: int, m: int, stat: str) -> float:
    a = _difference_rows(n_phase, m, *SPEC[stat])
    c = a @ a.T
    return float(np.trace(c) ** 2 / np.sum(c * c))


@pytest.mark.parametrize("stat", sorted(SPEC))
@pytest.mark.parametrize("n_phase", [129, 400])
def test_white_pm_edf_is_the_exact_quadratic_form_edf(stat, n_phase):
    for m in (1, 2, 4, 8, 16):
        if (SPEC[stat][0] + 1) * m >= n_phase / 3:
            continue
        assert edf_of(stat, 2, m, n_phase) == pytest.approx(_exact_edf_white_pm(n_phase, m, stat), rel=1e-9), m


@pytest.mark.parametrize("stat", sorted(SPEC))
@pytest.mark.parametrize("alpha", [1, 0, -1, -2])
def test_edf_agrees_with_allantools_greenhall(stat, alpha):
    d, overlapping, modified = SPEC[stat]
    if alpha + 2 * d <= 1:
        pytest.skip("Greenhall needs alpha + 2d > 1")
    for n_phase in (129, 400):
        for m in (1, 2, 4, 8):
            ref = allantools.edf_greenhall(alpha=alpha, d=d, m=m, N=n_phase, overlapping=overlapping,
                                           modified=modified)
            assert edf_of(stat, alpha, m, n_phase) == pytest.approx(ref, rel=1e-6), (n_phase, m)


@pytest.mark.parametrize("stat", ["oadev", "adev", "mdev", "ohdev"])
def test_pairs_used_give_the_edf_of_a_gap_free_record_with_as_many_terms(stat):
    """n_used terms (gaps skipped) -> the exact white-PM EDF of a record holding n_used terms."""
    d, overlapping, modified = SPEC[stat]
    for m in (1, 3, 8):
        for n_used in (40, 150):
            if overlapping:
                n_phase = n_used + (3 * m - 1 if modified else d * m)
            else:
                n_phase = (n_used + d - 1) * m + 1
            assert len(_difference_rows(n_phase, m, d, overlapping, modified)) == n_used  # the reference record
            ref = _exact_edf_white_pm(n_phase, m, stat)
            assert edf_of(stat, 2, m, 10 * n_phase, n_used) == pytest.approx(ref, rel=1e-9), (m, n_used)


def test_bounds_are_the_chi_squared_interval_of_the_edf():
    """lo, hi = dev sqrt(edf / chi2.ppf(1 - q)), dev sqrt(edf / chi2.ppf(q)), q = (1 - level) / 2 (scipy)."""
    rng = np.random.default_rng(15)
    x = rng.normal(0.0, 1e-9, 1024)
    curve = stability(x, 1.0, "oadev", "phase")
    for level in (0.683, 0.95):
        ci = intervals(curve, x, level, alpha=np.full(len(curve.m), 2.0))
        q = (1.0 - level) / 2.0
        for k in range(len(curve.m)):
            assert ci.edf[k] == pytest.approx(_exact_edf_white_pm(len(x), int(curve.m[k]), "oadev"), rel=1e-9)
            assert ci.lo[k] == pytest.approx(curve.dev[k] * np.sqrt(ci.edf[k] / sps.chi2.ppf(1 - q, ci.edf[k])), rel=1e-6)
            assert ci.hi[k] == pytest.approx(curve.dev[k] * np.sqrt(ci.edf[k] / sps.chi2.ppf(q, ci.edf[k])), rel=1e-6)


def test_white_pm_is_identified_where_enough_points_remain():
    """White PM phase: the lag-1 ACF of white noise is 0 +- 1/sqrt(L) (L decimated points), far from
    flicker PM's; with L >= 128 (m <= 32 of 4096 points) the rounded alpha is 2 at every such tau."""
    rng = np.random.default_rng(7)
    x = rng.normal(0.0, 1e-9, 4096)
    curve = stability(x, 1.0, "oadev", "phase")
    ci = intervals(curve, x)
    sel = curve.m <= 32
    assert sel.sum() >= 5
    assert np.all(ci.alpha[sel] == 2), ci.alpha


def test_simple_edf_agrees_with_allantools():
    """SP 1065's simple formulas (used for htotdev) against allantools' edf_simple (same formulas,
    independent code): float rounding."""
    for alpha in (2, 1, 0, -1, -2):
        for n_phase in (101, 1001):
            for m in (1, 2, 5, 16, 30):
                assert edf_simple(alpha, n_phase, m) == pytest.approx(allantools.edf_simple(n_phase, m, alpha),
                                                                      rel=1e-12), (alpha, n_phase, m)


@pytest.mark.parametrize("stat", ["totdev", "mtotdev", "htotdev", "theo1"])
@pytest.mark.parametrize("alpha", [2, 1, 0, -1, -2])
def test_total_and_theo1_edf_are_not_optimistic_against_monte_carlo(stat, alpha):
    """The EDF in use against the Monte Carlo EDF 2 E[s^2]^2 / var(s^2) of the estimator on R = 300
    power-law records of 1001 points (fixed seed). The Monte Carlo EDF's relative standard error is
    sqrt((2 + 12 / edf) / R) (the variance of R variance estimates with a chi-squared's excess
    kurtosis 12 / edf): ours may exceed it by 4 of those (never optimistic beyond the noise), and
    Theo1's (Howe & Tasset's fit) must be within a factor 2 of it (its flicker-PM formula had lost a
    factor r: 57 against 765 at m = 16)."""
    from workbench.sim.powerlaw import power_law_phase

    n, records = 1001, 300
    x = power_law_phase(alpha, n, records, np.random.default_rng(500 + alpha))
    v = np.array([stability(rec, 1.0, stat, "phase", "octave").dev ** 2 for rec in x])
    m = stability(x[0], 1.0, stat, "phase", "octave").m
    mc = 2.0 * v.mean(axis=0) ** 2 / v.var(axis=0, ddof=1)
    ours = np.array([edf_of(stat, alpha, int(mk), n) for mk in m])
    se = np.sqrt((2.0 + 12.0 / mc) / records)
    assert np.all(ours <= mc * (1.0 + 4.0 * se)), (m, ours, mc)
    if stat == "theo1":
        assert np.all(ours >= mc / 2.0), (m, ours, mc)
