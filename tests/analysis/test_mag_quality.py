"""Coverage and quality figures of a magnetometer calibration (workbench/analysis/mag_quality.py)
against closed forms and scipy's chi-squared test."""

import numpy as np
import pytest
from scipy import stats as sps
from scipy.spatial.transform import Rotation

from workbench.analysis.mag_fit import MagFit, nan33
from workbench.analysis.mag_quality import assess, gravity_spread, sphere_coverage, thickness


def _uniform_directions(n: int, seed: int) -> np.ndarray:
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _cells(u: np.ndarray, n_bands: int = 12, n_lon: int = 24) -> np.ndarray:
    """Cell counts of the module docstring's grid (bands equal in z, equal longitude sectors)."""
    band = np.minimum(((u[:, 2] + 1) / 2 * n_bands).astype(int), n_bands - 1)
    lon = np.minimum(((np.arctan2(u[:, 1], u[:, 0]) + np.pi) / (2 * np.pi) * n_lon).astype(int), n_lon - 1)
    return np.bincount(band * n_lon + lon, minlength=n_bands * n_lon)


def test_uniform_directions_cover_the_whole_sphere_in_equal_area_cells():
    """20 000 uniform directions over 288 cells: an empty cell has probability (1 - 1/288)^20000 ~ 1e-30,
    so coverage is 1; and the cells are of equal area (Archimedes), so the counts pass a chi-squared
    test of uniformity (p > 1e-4, a false alarm in 1e4 seeds)."""
    u = _uniform_directions(20_000, 1)
    assert sphere_coverage(u) == 1.0
    assert sps.chisquare(_cells(u)).pvalue > 1e-4


def test_a_level_yaw_sweep_covers_one_band():
    """Field at dip 60° turned through 360° about down: z = sin(60°) constant, every longitude: one
    band of 24 cells out of 288 (1/12)."""
    psi = np.linspace(0, 2 * np.pi, 3600, endpoint=False)
    u = np.column_stack([np.cos(np.radians(60)) * np.cos(psi), np.cos(np.radians(60)) * np.sin(psi),
                         np.full_like(psi, np.sin(np.radians(60)))])
    assert sphere_coverage(u) == pytest.approx(1 / 12)


def test_thickness_is_the_smallest_principal_deviation():
    """Gaussian cloud with principal std (20, 10, 0.3) µT, rotated: thickness = 0.3 µT; the sample std of
    N = 5000 points has relative sigma 1/sqrt(2N) = 1 %, 4 sigma."""
    rng = np.random.default_rng(2)
    n = 5000
    pts = rng.normal(size=(n, 3)) * [20.0, 10.0, 0.3]
    pts = Rotation.from_rotvec([0.4, -0.7, 1.1]).apply(pts) + [10.0, -5.0, 30.0]
    assert thickness(pts) == pytest.approx(0.3, rel=4 / np.sqrt(2 * n))


def test_gravity_spread_is_the_largest_tilt_from_the_mean():
    """Down directions on a 15° cone around z and z itself: the mean is z, the spread 15° (exact)."""
    a = np.radians(15.0)
    az = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    d = np.vstack([[0, 0, 1.0], np.column_stack([np.sin(a) * np.cos(az), np.sin(a) * np.sin(az), np.full(8, np.cos(a))])])
    assert gravity_spread(d) == pytest.approx(a, abs=1e-12)
    assert gravity_spread(np.tile([0.1, 0.0, 1.0], (5, 1))) == pytest.approx(0.0, abs=1e-7)


def _fit(method: str, bias, soft, norm: float) -> MagFit:
    return MagFit(method, np.asarray(bias, float), np.full(3, 0.1), np.asarray(soft, float), nan33(), norm, 0.1,
                  0.0, 0, "det")


def test_assess_norm_residual_and_warnings():
    """Raw points = S h + b, h uniform directions x 48 µT plus white noise 0.2 µT per axis; the true
    calibration gives a norm residual of the radial noise, std 0.2 µT (relative sigma 1/sqrt(2N) =
    1.6 % for N = 2000; 4 sigma), full coverage, no warning. A partial cap (z > 0.8) with the
    ellipsoid method warns of coverage; a 100 µT norm warns of the range."""
    rng = np.random.default_rng(4)
    n = 2000
    soft = np.eye(3) + np.array([[0.05, 0.01, 0.0], [0.01, -0.03, 0.02], [0.0, 0.02, 0.04]])
    bias = np.array([12.0, -30.0, 5.0])
    h = 48.0 * _uniform_directions(n, 5)
    raw = h @ soft.T + bias + rng.normal(0.0, 0.2, (n, 3)) @ soft.T
    q = assess(_fit("ellipsoid", bias, soft, 48.0), raw)
    assert q.norm_residual_rms_ut == pytest.approx(0.2, rel=4 / np.sqrt(2 * n))
    assert q.coverage == 1.0 and q.warnings == ()
    cap = raw[h[:, 2] > 0.8 * 48.0]
    q = assess(_fit("ellipsoid", bias, soft, 48.0), cap)
    assert q.coverage < 0.5 and any("coverage" in w for w in q.warnings)
    q = assess(_fit("sphere", bias, soft, 100.0), raw)
    assert any("outside the geomagnetic range" in w for w in q.warnings)
