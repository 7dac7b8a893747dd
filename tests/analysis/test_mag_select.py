"""Automatic choice of the magnetometer estimator (workbench/analysis/mag_select.py) from the quality
figures (workbench/analysis/mag_quality.py) of simulated point clouds: 48 µT, dip 60°, hard iron
(10, -20, 5) µT, white noise 0.3 µT per axis.

Thickness of a level yaw sweep: the noise, 0.3 µT < 2 µT; of any tilted cloud: > 4 µT (a ±15°
fixture, mag_quality's docstring). Tilt spread: 0 level, 30° for the tilted sets (> 5°).
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from workbench.analysis.mag_quality import gravity_spread, sphere_coverage, thickness
from workbench.analysis.mag_select import choose

FIELD = 48.0 * np.array([np.cos(np.radians(60)), 0.0, np.sin(np.radians(60))])
BIAS = np.array([10.0, -20.0, 5.0])


def _cloud(att: Rotation, seed: int):
    rng = np.random.default_rng(seed)
    raw = att.inv().apply(FIELD) + BIAS + rng.normal(0.0, 0.3, (len(att), 3))
    down = att.inv().apply([0.0, 0.0, 1.0])
    return raw, down


def _figures(raw, down, with_accel=True):
    return thickness(raw), sphere_coverage(raw - raw.mean(axis=0)), gravity_spread(down) if with_accel else None


def test_level_sweep_chooses_2d():
    att = Rotation.from_euler("z", np.linspace(0, 2 * np.pi, 720, endpoint=False)[:, None])
    th, cov, spread = _figures(*_cloud(att, 1))
    assert th < 1.0
    assert choose(th, cov, spread, has_attitude=True).method == "2d"


@pytest.fixture(scope="module")
def tilted():
    yaw = np.linspace(0, 2 * np.pi, 360, endpoint=False)
    att = Rotation.concatenate([Rotation.from_euler("ZY", np.column_stack([yaw, np.full(360, np.radians(p))]))
                                for p in (-30.0, 0.0, 30.0)])
    return _cloud(att, 2)


def test_tilted_sweeps_choose_attitude_with_table_angles_else_dip(tilted):
    th, cov, spread = _figures(*tilted)
    assert th > 4.0 and spread == pytest.approx(np.radians(30.0), abs=1e-6)
    assert choose(th, cov, spread, has_attitude=True).method == "attitude"
    assert choose(th, cov, spread, has_attitude=False).method == "dip"


def test_without_accelerometer_coverage_decides_ellipsoid_or_sphere(tilted):
    """All attitudes (uniform random): coverage ~1 >= 0.5 -> ellipsoid; the three yaw sweeps at -30, 0, +30° pitch cover a band
    of the sphere (< 0.5) -> sphere."""
    raw, down = _cloud(Rotation.random(3000, random_state=3), 3)
    th, cov, _ = _figures(raw, down, with_accel=False)
    assert cov > 0.9
    assert choose(th, cov, None, has_attitude=False).method == "ellipsoid"
    th, cov, _ = _figures(*tilted, with_accel=False)
    assert cov < 0.5
    choice = choose(th, cov, None, has_attitude=False)
    assert choice.method == "sphere" and f"{cov:.0%}" in choice.reason
