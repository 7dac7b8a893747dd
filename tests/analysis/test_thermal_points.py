"""Thermal measurements from a session (workbench.analysis.thermal_points): grouping of the steps."""

from types import SimpleNamespace

from workbench.analysis.thermal_points import SoakGroup, soak_groups


def _step(index, kind, t, temp=None):
    return SimpleNamespace(index=index, kind=kind, t_start=t, temperature_c=temp)


def test_each_soak_owns_the_steps_after_it_and_a_ramp_ends_the_group():
    steps = [_step(0, "soak", 0.0, -10.0), _step(1, "static", 10.0), _step(2, "static", 20.0),
             _step(3, "ramp", 30.0), _step(4, "static", 40.0),  # after a ramp, before a soak: no group
             _step(5, "soak", 50.0, 20.0), _step(6, "rate", 60.0), _step(7, "soak", 70.0, 50.0)]  # 7: empty
    groups = soak_groups(SimpleNamespace(steps=steps[::-1]))  # ordered by start time, not by list order
    assert groups == [SoakGroup(0, -10.0, (1, 2)), SoakGroup(5, 20.0, (6,))]
