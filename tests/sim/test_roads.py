"""Roads of the seed experiments (workbench/sim/roads.py): the legs say what the seeds describe."""

import numpy as np
import pytest

from workbench.sim import roads


def _time(leg: dict) -> float:
    return roads.leg_duration(leg)


def test_thesis_drive_timeline():
    road, odo, gps = roads.thesis_drive(seed=1)
    t = np.cumsum([_time(leg) for leg in road])
    stop = next(i for i, leg in enumerate(road) if leg.get("label") == "wheel deflation")
    start_of_stop = t[stop] - road[stop]["duration_s"]
    # the stop near 3000 s (legs padded to within the 20-s slow-down legs' margin), five minutes long
    assert start_of_stop == pytest.approx(roads.THESIS_STOP_S, abs=60.0)
    assert road[stop]["duration_s"] == roads.THESIS_STOP_DURATION_S
    assert t[-1] == pytest.approx(roads.THESIS_END_S, abs=120.0)
    # the odometer steps +4 % at the restart, just before the stop ends
    (t_step, pct), = odo["scale_steps"]
    assert pct == 4.0 and t[stop] - 10.0 < t_step < t[stop]
    assert gps["rate_hz"] == 1.0
    # the road keeps its heading within about +-100° of the start direction (turns turn back)
    heading = np.cumsum([leg.get("angle_deg", 0.0) for leg in road])
    assert np.abs(heading).max() < 200.0
    assert road == roads.thesis_drive(seed=1)[0] and road != roads.thesis_drive(seed=2)[0]


def test_precalibration_turns_back_to_the_start_azimuth():
    legs = roads.precalibration_legs()
    assert sum(leg.get("angle_deg", 0.0) for leg in legs) == 360.0
    assert sum(1 for leg in legs if leg["kind"] == "stop") == 5  # the alignment rest and four stops


@pytest.mark.parametrize("rate", [0.0, 0.3, -0.5])
def test_constant_rate_cruise(rate):
    legs = roads.constant_rate_drive(rate, speed_mps=20.0, duration_s=600.0, precalibration=False)
    cruise = legs[-1]
    assert cruise["label"] == "cruise" and _time(cruise) == pytest.approx(600.0)
    assert cruise.get("angle_deg", 0.0) == pytest.approx(rate * 600.0)
    assert cruise["speed_mps"] == 20.0
