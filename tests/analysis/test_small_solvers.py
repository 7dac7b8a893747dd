"""The fit's compiled NNLS and the numpy-only bracketed root finder against scipy.optimize (the independent reference)."""

import numpy as np
import pytest
from scipy.optimize import brentq, minimize_scalar
from scipy.optimize import nnls as scipy_nnls

from workbench.analysis.allan_fit_kernels import lstsq, nnls
from workbench.analysis.small_solvers import minimize_bounded, root_bracket


@pytest.mark.parametrize("seed", range(20))
def test_nnls_matches_scipy(seed):
    rng = np.random.default_rng(seed)
    m, n = rng.integers(5, 40), rng.integers(1, 8)
    a = rng.standard_normal((m, n)) * np.logspace(0, rng.uniform(0, 6), n)  # columns of very different scale
    b = rng.standard_normal(m) * 3.0
    x, r = nnls(a, b)
    x_ref, r_ref = scipy_nnls(a, b)
    assert np.all(x >= 0)
    # the solution is unique for full-rank a: equal to rounding of the passive-set solve
    assert r == pytest.approx(r_ref, rel=1e-9, abs=1e-12)
    assert np.allclose(x, x_ref, rtol=1e-7, atol=1e-10 * np.abs(x_ref).max(initial=1.0))


@pytest.mark.parametrize("seed", range(10))
def test_lstsq_matches_numpy(seed):
    # full-rank problems whose columns span up to 12 decades (condition ~1e4-1e9 before the column
    # scaling): the QR and numpy's SVD solutions agree to the condition of the scaled problem times eps
    rng = np.random.default_rng(100 + seed)
    m, n = rng.integers(6, 40), rng.integers(1, 6)
    a = rng.standard_normal((m, n)) * np.logspace(0, rng.uniform(0, 12), n)
    b = rng.standard_normal(m)
    ref = np.linalg.lstsq(a, b, rcond=None)[0]
    assert np.allclose(lstsq(a, b), ref, rtol=1e-9, atol=0.0)


def test_nnls_all_negative_gives_zero():
    a = np.eye(3)
    x, r = nnls(a, -np.ones(3))
    assert np.all(x == 0) and r == pytest.approx(np.sqrt(3))


@pytest.mark.parametrize("func,lo,hi", [(lambda t: t ** 3 - 2.0, 0.0, 4.0), (np.cos, 0.0, 3.0),
                                         (lambda t: np.exp(t) - 1e6, 0.0, 40.0),
                                         (lambda t: 1e-20 * (t - 3e-9), 0.0, 1e-8)])
def test_root_matches_brentq(func, lo, hi):
    ref = brentq(func, lo, hi, xtol=1e-14 * hi, rtol=1e-12)
    assert root_bracket(func, lo, hi, xtol=1e-14 * hi, rtol=1e-12) == pytest.approx(ref, rel=1e-10)


def test_root_needs_a_bracket():
    with pytest.raises(ValueError):
        root_bracket(lambda t: t * t + 1.0, -1.0, 1.0)


@pytest.mark.parametrize("func,lo,hi", [(lambda t: (t - 0.3) ** 2, -1.0, 2.0), (np.cos, 0.0, 6.0),
                                         (lambda t: np.abs(t - 1.7) + 0.1 * t, 0.0, 4.0),
                                         (lambda t: np.exp(t) - 3.0 * t, -2.0, 5.0),
                                         (lambda t: t, 0.0, 1.0)])  # the minimum at an end: approached, not reached
def test_minimize_bounded_matches_scipy(func, lo, hi):
    ref = minimize_scalar(func, bounds=(lo, hi), method="bounded", options={"xatol": 1e-9})
    x, fx = minimize_bounded(func, lo, hi, xtol=1e-9)
    assert lo < x < hi
    assert x == pytest.approx(ref.x, abs=1e-7) and fx == pytest.approx(ref.fun, abs=1e-9)


def test_minimize_bounded_steps_around_infinite_values():
    # a barrier (inf left of 1): the parabolic step is skipped, the golden section finds the minimum at 2
    x, fx = minimize_bounded(lambda t: np.inf if t < 1.0 else (t - 2.0) ** 2, 0.0, 5.0, xtol=1e-8)
    assert x == pytest.approx(2.0, abs=1e-6) and fx < 1e-10
