"""Site and StepRecord (workbench.session_types): units, round trip, one-line errors naming the step."""

import math

import numpy as np
import pytest

from workbench.earth import normal_gravity
from workbench.errors import SessionError
from workbench.session_types import FLAG_REPEATED, FLAG_SATURATED, STEP_KINDS, Site, StepRecord


def test_site_degrees_in_the_file_radians_and_gravity_by_property():
    s = Site(45.0, 7.0, 250.0, 90.0)
    assert s.latitude == pytest.approx(math.pi / 4) and s.table_zero_azimuth == pytest.approx(math.pi / 2)
    assert s.gravity == pytest.approx(normal_gravity(math.pi / 4, 250.0))
    assert Site(45.0).table_zero_azimuth is None
    assert "field_norm_ut" not in s.to_dict() and Site(45.0, field_norm_ut=48.0).to_dict()["field_norm_ut"] == 48.0


def test_step_record_round_trip_keeps_extra_keys():
    mount = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    s = StepRecord(3, "rate", 1.0, 11.0, mount, 0.5, 0.2, 25.0, "spin", {"revolutions": 2})
    back = StepRecord.from_dict(s.to_dict())
    assert back.duration == 10.0 and back.extra == {"revolutions": 2} and back.label == "spin"
    assert np.array_equal(back.mount, mount) and (back.table_angle, back.table_rate, back.temperature_c) == (0.5, 0.2, 25.0)


@pytest.mark.parametrize("d,match", [
    ({"kind": "static", "t_start": 0, "t_end": 1}, "no integer 'index'"),
    ({"index": 2, "kind": "spin", "t_start": 0, "t_end": 1}, "step 2: unknown kind 'spin'"),
    ({"index": 2, "kind": "static", "t_start": 0}, "step 2: missing field 't_end'"),
    ({"index": 2, "kind": "static", "t_start": 1, "t_end": 1}, "step 2: t_end 1.0 is not after"),
    ({"index": 2, "kind": "static", "t_start": 0, "t_end": 1, "mount": [[1, 0, 0], [0, 1, 0], [0, 0, -1]]},
     "step 2: 'mount' is not a rotation"),
])
def test_step_record_errors_name_file_and_step(d, match):
    with pytest.raises(SessionError, match=match) as e:
        StepRecord.from_dict(d, "x/session.json")
    assert str(e.value).startswith("x/session.json: ")


def test_flag_bits_are_distinct_and_every_kind_parses():
    bits = [*FLAG_SATURATED.values(), *FLAG_REPEATED.values()]
    assert len(set(bits)) == 6 and all(b & (b - 1) == 0 for b in bits)  # six distinct single bits
    assert [StepRecord.from_dict({"index": 0, "kind": k, "t_start": 0, "t_end": 1}).kind for k in STEP_KINDS] == \
        list(STEP_KINDS)
