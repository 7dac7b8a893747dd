import numpy as np
import pytest

from workbench.errors import RigLimitError
from workbench.rigconfig import load_rig_config
from workbench.sequence import (Carousel, Hold, Index, Ramp, Repeat, Rotate, Sequence, Soak, mount_from_euler,
                                mount_label, mount_matrix)
from workbench.sim.rig import SimRig


def test_named_mounts_put_the_axis_up():
    for axis, i in (("x", 0), ("y", 1), ("z", 2)):
        up = mount_matrix(f"{axis}-up") @ np.eye(3)[i]
        assert np.allclose(up, [0, 0, -1])  # table z is down
        assert np.allclose(mount_matrix(f"{axis}-down") @ np.eye(3)[i], [0, 0, 1])
        assert mount_label(mount_matrix(f"{axis}-up")) == f"{axis}-up"
    assert mount_label(mount_from_euler("x", [30.0])).endswith("tilted 30°")


def test_expand_serialise_and_describe():
    seq = Sequence("all-kinds", [
        Hold("x-up", 0.0, 10.0), Index(np.pi, 5.0), Rotate("z-down", np.radians(90), revolutions=2),
        Carousel("z-down", np.radians(30), laps=1), Soak(30.0, "z-down"),
        Ramp(35.0, 1.0, positions=[["x-up", 0.0], ["x-down", 0.0]], dwell_s=60.0),
        Repeat([Hold("y-up", dwell_s=1.0), Hold("y-down", dwell_s=1.0)], count=3)], start_temperature_c=23.0)
    plan = seq.expand()
    kinds = [p.kind for p in plan]
    assert kinds[:7] == ["static", "index", "static", "rate", "carousel", "soak", "ramp"]
    assert kinds.count("ramp") == 5 and len(plan) == 7 + 4 + 6
    assert plan[2].table_angle == pytest.approx(np.pi)
    assert plan[3].duration_s == pytest.approx(8.0)  # 2 revolutions at 90 deg/s
    again = Sequence.from_json(seq.to_json())
    assert [p.to_dict() for p in again.expand()] == [p.to_dict() for p in plan]
    rows = seq.describe()
    assert rows[0]["mount"] == "x-up" and rows[3]["table_rate_dps"] == pytest.approx(90.0)


@pytest.mark.parametrize("step,match", [
    (Rotate("z-down", np.radians(2000)), "exceeds the limit"),
    (Soak(200.0), "outside"),
    (Hold("q-up"), "unknown mount"),
    (Hold("z-down", dwell_s=-1), "must be positive"),
])
def test_rig_refuses_out_of_limit_sequences_before_running(step, match):
    from workbench.grades import draw_unit, load_spec

    rig = SimRig(load_rig_config("sim"), draw_unit(load_spec("industrial_mems"), 1), 1)
    with pytest.raises(RigLimitError, match=match):
        rig.check(Sequence("bad", [Hold("z-down"), step]).expand())
    assert rig.state.sample == 0  # nothing ran


def test_too_fast_ramp_is_refused():
    seq = Sequence("r", [Soak(23.0), Ramp(60.0, 20.0)], start_temperature_c=23.0)
    from workbench.grades import draw_unit, load_spec

    rig = SimRig(load_rig_config("sim"), draw_unit(load_spec("industrial_mems"), 1), 1)
    with pytest.raises(RigLimitError, match="step 1 .*ramp 20.00 °C/min exceeds"):
        rig.check(seq.expand())


def test_free_step_expands_and_round_trips():
    from workbench.sequence import Free
    from workbench.session import STEP_KINDS

    seq = Sequence("by-hand", [Free(30.0, "tumble")])
    (p,) = seq.expand()
    assert p.kind == "free" and p.kind in STEP_KINDS and p.duration_s == 30.0 and p.table_rate == 0.0
    assert Sequence.from_json(seq.to_json()).expand()[0].kind == "free"
    with pytest.raises(RigLimitError, match="Free.duration_s"):
        Sequence("bad", [Free(0.0)]).expand()
