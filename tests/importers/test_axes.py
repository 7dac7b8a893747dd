"""Axis check against the virtual lab's hand-held recording: right axes agree, a flipped or swapped axis is named."""

import numpy as np
import pytest

from workbench.grades import draw_unit
from workbench.grade_fixtures import load_spec
from workbench.importers.axes import CLEAR, check_axes, describe, signed_permutations
from workbench.sim.handheld import handheld_session


@pytest.fixture(scope="module")
def held():
    unit = draw_unit(load_spec("consumer_9axis"), 7)
    session, _ = handheld_session(unit, 7, duration_s=40.0, still_s=1.0)
    s = session.samples
    return s["t"].to_numpy(), session.gyro(), session.accel(), session.mag()


@pytest.mark.parametrize("reference", ["accel", "mag"])
def test_right_axes_agree(held, reference):
    t, gyro, accel, mag = held
    c = check_axes(t, gyro, accel if reference == "accel" else mag, reference)
    assert c.windows >= 20 and c.agrees is True and np.allclose(c.best, np.eye(3))


@pytest.mark.parametrize("wrong", [np.diag([1.0, -1.0, 1.0]), np.array([[0, 1.0, 0], [1.0, 0, 0], [0, 0, -1.0]])])
@pytest.mark.parametrize("reference", ["accel", "mag"])
def test_a_flipped_or_swapped_gyro_axis_is_named(held, wrong, reference):
    t, gyro, accel, mag = held
    c = check_axes(t, gyro @ wrong.T, accel if reference == "accel" else mag, reference)
    assert c.agrees is False
    assert np.allclose(c.best, wrong.T)  # the mapping that undoes it
    assert describe(c.best) in c.message() and "DISAGREE" in c.message()
    assert c.rms_best_deg < CLEAR * c.rms_identity_deg


def test_a_still_record_gives_no_verdict(held):
    t, gyro, accel, _ = held
    n = len(t)
    c = check_axes(t, 1e-4 * np.ones((n, 3)), np.tile([0.0, 0.0, -9.8], (n, 1)), "accel")
    assert c.agrees is None and "not enough motion" in c.message()


def test_the_48_signed_permutations():
    ps = signed_permutations()
    assert len(ps) == 48 and np.allclose(ps[0], np.eye(3))
    assert len({tuple(p.ravel()) for p in ps}) == 48 and all(np.allclose(p @ p.T, np.eye(3)) for p in ps)
