from dataclasses import replace

import numpy as np
import pytest

from workbench.earth import earth_rate_ned, normal_gravity
from workbench.rigconfig import load_rig_config
from workbench.sequence import Carousel, Hold, Index, Ramp, Rotate, Sequence, Soak
from workbench.jobs import simulate


@pytest.fixture(scope="module")
def exact_rig():
    cfg = load_rig_config("sim")
    return replace(cfg, turntable=replace(cfg.turntable, positioning_error=0.0))


def test_static_means_match_error_model_of_gravity_and_earth_rate(exact_rig):
    mounts = ["x-up", "x-down", "y-up", "y-down", "z-up", "z-down"]
    seq = Sequence("six", [Hold(m, np.radians(30.0), 60.0) for m in mounts])
    session, truth = simulate(seq, "industrial_mems", seed=3, rig=exact_rig)
    g = normal_gravity(session.site.latitude, session.site.height_m)
    w_ie = earth_rate_ned(session.site.latitude)
    fs, n = session.sample_rate_hz, 60 * session.sample_rate_hz
    # tolerance: 5 sigma of a 60 s mean of white noise plus bias instability (ADEV floor 0.664 B at 60 s)
    tol_a = 5 * np.hypot(truth.accel_noise.white / np.sqrt(60.0), truth.accel_noise.bias_instability)
    tol_g = 5 * np.hypot(truth.gyro_noise.white / np.sqrt(60.0), truth.gyro_noise.bias_instability)
    for step in session.steps:
        c_bn = session.attitude(step).as_matrix()
        f_b = c_bn.T @ np.array([0, 0, -g])
        w_b = c_bn.T @ w_ie
        temp = session.step_samples(step.index)["temp"].mean()
        exp_a = truth.accel.apply(f_b[None], temperature_c=temp)[0]
        exp_g = truth.gyro.apply(w_b[None], f_b[None], temperature_c=temp)[0]
        assert np.all(np.abs(session.accel(step.index).mean(0) - exp_a) < tol_a), step.label
        assert np.all(np.abs(session.gyro(step.index).mean(0) - exp_g) < tol_g), step.label
    assert len(session.samples) > 6 * n and fs == truth.sample_rate_hz


def test_rate_index_and_carousel_motion(exact_rig):
    seq = Sequence("motion", [Hold("z-down", 0.0, 2.0), Index(np.pi / 2, 2.0, np.radians(45)),
                              Rotate("z-down", np.radians(60.0), revolutions=2),
                              Carousel("x-up", np.radians(-20.0), laps=1)])
    s, truth = simulate(seq, "navigation_grade", seed=1, rig=exact_rig)
    idx = s.steps[1]
    assert idx.kind == "index"
    # the encoder angle advances by exactly the index angle over the index step (to its resolution)
    ang = np.unwrap(s.step_samples(idx.index)["table_angle"].to_numpy())
    assert ang[-1] - s.step_samples(0)["table_angle"].iloc[-1] == pytest.approx(np.pi / 2, abs=1e-3)
    hold = s.steps[2]
    assert hold.table_angle == pytest.approx(np.pi / 2, abs=1e-4)
    rate = s.steps[3]
    # the gyro integral over whole revolutions: (1 + sf) * 720 deg, sf = M[2,2]
    turned = s.gyro(rate.index)[:, 2].sum() / s.sample_rate_hz
    expected = (1 + truth.gyro.scale_misalignment[2, 2]) * 4 * np.pi
    assert turned == pytest.approx(expected, abs=np.radians(0.5))
    car = s.steps[4]
    assert car.kind == "carousel" and car.extra["revolutions"] == pytest.approx(1.0)
    # x-up: the table's down rate appears on -x
    assert s.gyro(car.index)[:, 0].mean() == pytest.approx(np.radians(20.0), rel=0.01)


def test_soak_settles_on_unit_temperature_and_ramp_follows():
    seq = Sequence("thermal", [Soak(33.0, "z-down", settle_tol_c_per_min=0.02, settle_window_s=120.0),
                               Ramp(38.0, 1.0, "z-down")], start_temperature_c=23.0)
    s, truth = simulate(seq, "consumer_9axis", seed=2)
    soak = s.steps[0]
    temp = s.step_samples(soak.index)["temp"].to_numpy()
    # settled: within 0.02 C/min x tau of the setpoint is the first-order lag criterion
    assert abs(temp[-200:].mean() - 33.0) < 0.02 * truth.thermal_time_constant_s / 60 + 0.05
    assert soak.duration > 3 * truth.thermal_time_constant_s  # not an assumed fixed time
    ramp = s.steps[1]
    assert ramp.duration == pytest.approx(5 * 60.0, abs=1.0)
    t = s.step_samples(ramp.index)
    slope = np.polyfit(t["t"], t["temp"], 1)[0] * 60
    assert 0.5 < slope <= 1.0  # the unit lags the 1 C/min air ramp


def test_soak_that_never_settles_is_a_clear_error():
    from workbench.errors import RigError

    seq = Sequence("s", [Soak(80.0, "z-down", max_s=300.0)], start_temperature_c=23.0)
    with pytest.raises(RigError, match="step 0 .*did not settle within 300 s"):
        simulate(seq, "industrial_mems", seed=1)
