"""RealRig and open_real_rig: configuration errors, limits, interlocks, safe stops, resume."""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np
import pytest
import yaml

import procedures.multiposition as mp
from tests.drivers.conftest import FS, hil_yaml
from workbench.calset import Unit
from workbench.drivers.rig import open_real_rig
from workbench.errors import RigError, RigLimitError, WorkbenchError
from workbench.grades import draw_unit, load_spec
from workbench.jobs import open_rig, record_procedure, resume_procedure
from workbench.rigconfig import RIGS_DIR, load_rig_config
from workbench.runner import PARTS, read_parts, record, start
from workbench.sequence import Hold, Index, Rotate, Sequence
from workbench.session import load_session

SPEC = load_spec("industrial_mems")


@pytest.fixture
def hil(tmp_path, start_lab, closing):
    """A running loopback lab, its configuration file, and a connected rig."""
    path = hil_yaml(tmp_path)
    truth = replace(draw_unit(SPEC, 2), sample_rate_hz=FS)
    lab = start_lab(path, truth=truth, seed=3)
    return lab, path, truth


def test_unknown_driver_and_missing_fields(tmp_path):
    with pytest.raises(WorkbenchError, match=r"hil-0.yaml: driver: unknown driver 'acme' \(known: sim, real\)"):
        load_rig_config(hil_yaml(tmp_path, driver="acme"))  # the schema refuses it on load
    cfg = load_rig_config(hil_yaml(tmp_path))
    with pytest.raises(RigError, match=r"rig hil-acutrol-espec: unknown driver 'acme' \(known: sim, real\)"):
        open_rig(replace(cfg, driver="acme"), None, 0)  # and a configuration built in code is refused on open
    opts = {k: v for k, v in cfg.options.items() if k != "imu_stream"}
    with pytest.raises(RigError, match=r"rig hil-acutrol-espec: missing field 'imu_stream'"):
        open_real_rig(replace(cfg, options=opts))
    bad = {**cfg.options, "chamber_controller": {"driver": "telnet"}}
    with pytest.raises(RigError, match=r"chamber: unknown chamber_controller.driver 'telnet' \(known: ascii, modbus\)"):
        open_real_rig(replace(cfg, options=bad))


def test_address_that_does_not_answer(tmp_path):
    cfg = load_rig_config(hil_yaml(tmp_path))  # free ports, nothing started
    with pytest.raises(RigError, match=r"rig hil-acutrol-espec: turntable \(TCPIP0::127\.0\.0\.1::\d+::SOCKET\): "
                                       r"cannot open"):
        open_real_rig(cfg)


def test_identify_moves_nothing(hil, closing):
    lab, path, _ = hil
    rig = closing(open_real_rig(load_rig_config(path)))
    info = rig.identify()
    assert info["table"].startswith("HIL") and info["interlock"] == "clear"
    assert info["position_moves"] == "rate and acceleration limit sent"
    assert info["air_c"] == pytest.approx(23.0, abs=0.01)
    assert info["table_angle_deg"] == 0.0 and lab.sim.state.table_rate == 0.0


def test_limits_checked_before_anything_moves(hil, closing):
    lab, path, _ = hil
    cfg = load_rig_config(path)
    rig = closing(open_real_rig(cfg))
    too_fast = Sequence("fast", [Hold("z-down", 0.0, 1.0), Rotate("z-down", np.radians(1500.0), 1.0)])
    with pytest.raises(RigLimitError, match=r"step 1 \(rate\): table rate 1500\.0 °/s exceeds the limit 1000\.0 °/s"):
        start(too_fast, rig, Unit("u", "m"), "fast", None)
    fixed = closing(open_real_rig(replace(cfg, options={**cfg.options, "fixture": {"mode": "fixed"}})))
    with pytest.raises(RigLimitError, match=r"step 1 \(static, x-down\): needs a remount to x-down but fixture"):
        start(mp.sequence(SPEC, dwell_s=1.0), fixed, Unit("u", "m"), "mp", None)
    assert lab.sim.state.sample > 0 and lab.sim.state.table_rate == 0.0 and lab.sim.state.table_angle == 0.0


def _interrupt(lab, after_step: int, device: str, fault: str):
    def progress(i, n, rec):
        if i == after_step:
            lab.inject(device, fault)
    return progress


def test_interlock_stops_the_run_with_the_step_named(hil, closing, caplog):
    lab, path, truth = hil
    rig = closing(open_real_rig(load_rig_config(path)))
    rec = start(mp.sequence(SPEC, dwell_s=2.0), rig, Unit(truth.serial, truth.model), mp.NAME, None)
    with caplog.at_level(logging.WARNING, "workbench.rig"), pytest.raises(
            RigError, match=r"rig hil-acutrol-espec: step 1 \(static, x-down\): .*interlock reported by the "
                            r"controller: 1 \(INTERLOCK DOOR OPEN\)"):
        record(rec, rig, _interrupt(lab, 0, "table", "interlock"))
    assert "table stopped; chamber set to its safe setpoint 23 °C" in caplog.text
    assert rec.done == 1


DROPPED = {  # device -> what the error names
    "table": r"turntable \(TCPIP0::127\.0\.0\.1::\d+::SOCKET\): connection lost during '",
    "chamber": r"chamber \(socket://127\.0\.0\.1:\d+\): connection lost during 'TEMP\?'",
    "stream": r"imu stream \(socket://127\.0\.0\.1:\d+\): connection lost after sample \d+",
}


@pytest.mark.parametrize("device", list(DROPPED))
def test_dropped_link_stops_safely_and_resume_continues(device, hil, tmp_path, caplog):
    lab, path, truth = hil
    cfg = load_rig_config(path)
    out = tmp_path / "session"

    def drop_after_step_1(i, n, rec):
        if i == 1:
            lab._set_chamber(40.0)  # the chamber is away from its safe setpoint when the link drops
            lab.inject(device, "drop")

    with caplog.at_level(logging.WARNING, "workbench.rig"), pytest.raises(
            RigError, match=r"rig hil-acutrol-espec: step 2 \(static, y-up\): .*" + DROPPED[device]):
        record_procedure(mp, SPEC, truth, cfg, 3, out, {"dwell_s": 2.0}, drop_after_step_1)
    # made safe and said so: the STOP got through (on a fresh link if needed), the chamber went to 23 °C
    assert "run stopped; table stopped; chamber set to its safe setpoint 23 °C" in caplog.text
    assert lab.sim.state.chamber_target_c == 23.0 and lab._hold == 0.0
    # completed steps stay readable
    parts = read_parts(out)
    assert sorted(set(parts["step"]) - {-1}) == [0, 1]
    assert len(list((out / PARTS).glob("step_*.parquet"))) == 2
    # --resume continues from step 2 on the same time axis and completes the session
    session = resume_procedure(out)
    assert [s.index for s in session.steps] == list(range(6))
    assert session.steps[2].t_start > session.steps[1].t_end
    assert load_session(out).steps[5].label == "z-down"
    assert mp.analyze(session).calibration is not None
    # every step holds samples of its own position only: its mean matches the truth at that mount.
    # Noise of a 2 s position mean (m/s^2): white 8.3e-4/sqrt(2 s) = 5.9e-4, bias instability 5.6e-4, fixture
    # tilt 0.01° x g = 1.7e-3 cross-axis: combined 1.9e-3 (0.19 mg); 5 sigma = 9.5e-3, i.e. 1 mg. One sample
    # of another mount among the 100 would shift the mean by g / 100 = 10 mg.
    g = session.site.gravity
    for st in session.steps:
        x = session.step_samples(st.index)
        f = np.asarray(st.mount).T @ np.array([0.0, 0.0, -g])
        expected = truth.accel.apply(f[None], None, float(x["temp"].mean()))[0]
        assert np.all(np.abs(x[["ax", "ay", "az"]].mean().to_numpy() - expected) < 9.80665e-3), st.label


def test_ctrl_c_makes_the_rig_safe(hil, closing, caplog):
    lab, path, truth = hil
    rig = closing(open_real_rig(load_rig_config(path)))
    lab._set_chamber(-20.0)
    rec = start(Sequence("spin", [Rotate("z-down", np.radians(30.0), duration_s=10.0)]), rig,
                Unit(truth.serial, truth.model), "spin", None)

    def ctrl_c(i, n, r):
        raise KeyboardInterrupt

    with caplog.at_level(logging.WARNING, "workbench.rig"), pytest.raises(KeyboardInterrupt):
        record(rec, rig, ctrl_c)
    assert "table stopped" in caplog.text
    assert lab._hold == 0.0 and lab.sim.state.chamber_target_c == 23.0


def test_corrupt_stream_stops_the_run_naming_step_and_frame(hil, closing):
    lab, path, truth = hil
    rig = closing(open_real_rig(load_rig_config(path)))
    rec = start(Sequence("hold", [Hold("z-down", 0.0, 3.0), Hold("z-down", 1.0, 3.0)]), rig,
                Unit(truth.serial, truth.model), "hold", None)
    with pytest.raises(RigError, match=r"step 1 \(static\): rig hil-acutrol-espec: imu stream \(socket://127\.0\.0\.1:"
                                       r"\d+\): frame after sample \d+ does not parse \(checksum mismatch\)"):
        record(rec, rig, _interrupt(lab, 0, "stream", "corrupt"))


def test_stream_timestamp_jump_stops_the_run(hil, closing):
    lab, path, truth = hil
    rig = closing(open_real_rig(load_rig_config(path)))
    rec = start(Sequence("hold", [Hold("z-down", 0.0, 3.0), Hold("z-down", 1.0, 3.0)]), rig,
                Unit(truth.serial, truth.model), "hold", None)
    with pytest.raises(RigError, match=r"step 1 \(static\): .*imu stream .*timestamps jump at frame \d+ after sample "
                                       r"\d+: counter \d+ -> \d+ \(51 sample intervals\)"):
        record(rec, rig, _interrupt(lab, 0, "stream", "jump"))


def test_soak_ramp_and_rotation_through_the_drivers(tmp_path, start_lab, closing):
    from workbench.sequence import Ramp, Soak

    # a unit with a 10 s thermal lag keeps the soak short (the chamber air moves at 5 °C/min)
    truth = replace(draw_unit(SPEC, 4), sample_rate_hz=FS, thermal_time_constant_s=10.0, temp_sensor_noise_c=0.0)
    lab = start_lab(hil_yaml(tmp_path, hil={"speed": 40.0}), truth=truth, seed=5)
    rig = closing(open_real_rig(lab.config))
    rate = np.radians(30.0)
    seq = Sequence("thermal", [Soak(26.0, "z-down", 0.0, settle_tol_c_per_min=0.05, settle_window_s=30.0, max_s=600.0),
                               Ramp(27.0, 2.0, "z-down"), Rotate("z-down", rate, duration_s=10.0),
                               Hold("x-up", 0.0, 1.0)])  # remount: stops the rotation first
    session = record(start(seq, rig, Unit(truth.serial, truth.model), "thermal", None), rig)
    soak, ramp, spin, hold = session.steps  # the session validated: no gaps in the samples
    temp = session.samples["temp"].to_numpy()
    at = session.samples["step"].to_numpy()
    # soak: settled = slope < 0.05 °C/min; with a 10 s lag the slope is e / 10 s * 60, so the remaining
    # error e < 0.008 °C when the soak ends (0.05 °C leaves room for the 0.01 °C read-back resolution)
    assert abs(temp[at == soak.index][-1] - 26.0) < 0.05
    assert soak.duration > 36.0  # the air alone needs 3 °C / (5 °C/min) = 36 s
    # ramp: the host stepped the setpoint from 26 to 27 °C over 30 s, the unit warmed with it
    assert ramp.duration == pytest.approx(30.0, abs=2.0 / FS)
    assert lab.sim.state.chamber_target_c == pytest.approx(27.0, abs=0.05)
    t_ramp = temp[at == ramp.index]
    assert t_ramp[-1] - t_ramp[0] > 0.5  # 1 °C of air in 30 s, lagged by 10 s: ~0.67 °C
    # rotation: read-back rate on every sample, angle advancing by rate / fs per sample
    s = session.samples[at == spin.index]
    np.testing.assert_allclose(s["table_rate"], rate, atol=np.radians(0.01))
    steps = np.diff(np.unwrap(s["table_angle"].to_numpy()))
    assert np.median(steps) == pytest.approx(rate / FS, rel=1e-3)
    # gyro z (down, z-down mount) sees table rate + Earth rate + bias: within 1 °/s of the table rate
    assert s["gz"].mean() == pytest.approx(rate, abs=np.radians(1.0))
    # after the remount the table is at rest with the unit x-up: accel x reads +g (specific force points up;
    # bias and scale-factor errors of this grade stay below 0.1 m/s^2)
    h = session.samples[at == hold.index]
    assert h["table_rate"].abs().max() == 0.0 and h["ax"].mean() == pytest.approx(9.80, abs=0.1)


INDEX = np.radians(90.0)  # rad: a quarter turn, no ambiguity in the direction of an absolute move


def _index_run(lab, path, truth, rate_dps: float, angle: float = INDEX):
    """Hold, then Index by ``angle`` at ``rate_dps`` (z-down, so gz is the table rate) through the real drivers."""
    seq = Sequence("index", [Hold("z-down", 0.0, 1.0), Index(angle, 1.0, np.radians(rate_dps))])
    rig = open_real_rig(load_rig_config(path))
    try:
        session = record(start(seq, rig, Unit(truth.serial, truth.model), "index", None), rig)
    finally:
        rig.close()
    step = next(s for s in session.steps if s.kind == "index")
    df = session.samples[session.samples["step"] == step.index]
    # gyro output -> true body rate with the unit's own truth model (bias, scale factor, thermal terms)
    gyro = truth.gyro.compensate(df[["gx", "gy", "gz"]].to_numpy(), df[["ax", "ay", "az"]].to_numpy(),
                                 df["temp"].to_numpy())
    return step, df, gyro[:, 2]


def _gyro_plateau_rate(wz: np.ndarray, rate: float, expected: float) -> float:
    """Median |wz| (rad/s) over the samples above half ``rate``, checked against the table rate ``expected``.

    The unit's truth model is removed, so on the plateau |wz| = table rate - Earth rate 9.8 °/h (z down, 40.8° N).
    ARW 0.2 °/sqrt(h) = 0.024 °/s per sample at 50 Hz: the median of n samples has sigma 1.25 * 0.024 / sqrt(n)
    °/s; bias instability 8 °/h = 0.0022 °/s; the trapezoid's ramps (500 °/s^2) last < 2 samples. 4 sigma.
    """
    plateau = np.abs(wz) > 0.5 * rate
    median = float(np.median(np.abs(wz[plateau])))
    earth_z = np.radians(15.041 / 3600) * np.sin(np.radians(40.8))
    tol = 4 * np.radians(np.hypot(1.25 * 0.024 / np.sqrt(plateau.sum()), 0.0022))
    assert abs(median - (expected - earth_z)) < tol, (np.degrees(median), plateau.sum())
    return median


@pytest.mark.parametrize("base", ["hil", "hil_modbus"])  # POS:RATE + POS:ACC before POS:COMM | MOVE {angle},{rate}
def test_index_runs_at_the_sequence_index_rate(base, tmp_path, start_lab):
    path = hil_yaml(tmp_path, base)
    truth = replace(draw_unit(SPEC, 2), sample_rate_hz=FS)
    lab = start_lab(path, truth=truth, seed=3)
    rate = np.radians(15.0)
    step, df, wz = _index_run(lab, path, truth, 15.0)
    # the move carried the index rate (and, on hil.yaml, the acceleration limit 500 °/s^2 of turntable.max_accel_dps2)
    moves = [(key, f) for _, key, f in lab.table_log if key.startswith("position")]
    index_move = [("position_rate", {"rate_dps": "15.00000"}), ("position_accel", {"accel_dps2": "500.00000"}),
                  ("position_relative", {"delta_deg": "90.00000"})] if base == "hil" else \
        [("position", {"angle_deg": "90.00000", "rate_dps": "15.00000"})]
    assert any(moves[k:k + len(index_move)] == index_move for k in range(len(moves))), moves
    assert step.extra["index_rate_sent"] is True
    # Read-back: the simulator fits the trapezoid to whole samples (n = ceil((90°/15 + 15/500) s * 50 Hz) = 302),
    # which moves its plateau by less than one sample in n: |peak - rate| < rate / n.
    n = np.ceil((INDEX / rate + rate / np.radians(500.0)) * FS)
    # (polled once per poll_s = 0.5 s of samples: the 6 s move is seen on its plateau)
    peak = np.abs(df["table_rate"].to_numpy()).max()
    assert abs(peak - rate) < rate / n, np.degrees(peak)
    # The motion itself, from the unit's gyro
    gyro_rate = _gyro_plateau_rate(wz, rate, peak)
    print(f"{base}: index 90° at 15 °/s: read-back peak {np.degrees(peak):.5f} °/s, gyro plateau "
          f"{np.degrees(gyro_rate):.4f} °/s")


def test_index_turns_the_way_the_sequence_says_with_a_relative_move(tmp_path, start_lab):
    # -270°: an absolute move to the same angle would take the short way, +90°
    path = hil_yaml(tmp_path, "hil")
    truth = replace(draw_unit(SPEC, 2), sample_rate_hz=FS)
    lab = start_lab(path, truth=truth, seed=3)
    step, df, wz = _index_run(lab, path, truth, 60.0, np.radians(-270.0))
    assert ("position_relative", {"delta_deg": "-270.00000"}) in [(k, f) for _, k, f in lab.table_log]
    # the gyro integrates the turn to -270° (the short way would give +90°); 0.1° covers Earth rate
    # over the 5.5 s step (0.015°), ARW (0.2 °/sqrt(h): 0.007°), the settle tolerance (0.005°) and the
    # sampled ramps of the trapezoid
    turned = np.degrees(np.sum(wz) / FS)
    assert turned == pytest.approx(-270.0, abs=0.1), turned
    assert np.all(np.degrees(wz[np.abs(wz) > np.radians(30.0)]) < 0)


def test_index_rate_without_a_rate_command_falls_back_with_a_warning(tmp_path, start_lab, caplog):
    commands = {**yaml.safe_load((RIGS_DIR / "hil.yaml").read_text())["table_controller"]["commands"],
                "position_rate": None}
    path = hil_yaml(tmp_path, table_controller={"commands": commands})
    truth = replace(draw_unit(SPEC, 2), sample_rate_hz=FS)
    lab = start_lab(path, truth=truth, seed=3)
    with caplog.at_level(logging.WARNING, "workbench.rig"):
        step, df, wz = _index_run(lab, path, truth, 15.0)
    assert f"{path}: no 'position_rate' in table_controller.commands (nor {{rate_dps}} in 'position'): index steps " \
           "run at the controller's own slew rate, not at 15 °/s" in caplog.text
    assert step.extra["index_rate_sent"] is False
    assert not any(key == "position_rate" for _, key, _ in lab.table_log)
    # the simulated controller's own position-mode rate, 60 °/s (a 90° move fits it in whole samples exactly);
    # the 1.6 s move falls between two read-back polls of the fast loopback, so the gyro shows it
    gyro_rate = _gyro_plateau_rate(wz, np.radians(60.0), np.radians(60.0))
    print(f"fallback: index 90° asked at 15 °/s ran at {np.degrees(gyro_rate):.4f} °/s (gyro plateau)")


def test_index_rate_and_position_commands_checked_before_anything_moves(hil, closing):
    lab, path, truth = hil
    cfg = load_rig_config(path)
    unit = Unit(truth.serial, truth.model)
    too_fast = Sequence("fast", [Hold("z-down", 0.0, 1.0), Index(np.pi, 1.0, np.radians(1500.0))])
    with pytest.raises(RigLimitError, match=r"step 1 \(index\): table rate 1500\.0 °/s exceeds the limit 1000\.0"):
        start(too_fast, closing(open_real_rig(cfg)), unit, "fast", None)
    seq = Sequence("ok", [Hold("z-down", 0.0, 1.0), Index(np.pi, 1.0)])
    tc = cfg.options["table_controller"]
    bad = {**tc, "commands": {**tc["commands"], "position_rate": "POS:RATE {speed:.3f}"}}
    with pytest.raises(RigError, match=r"table_controller.commands.position_rate 'POS:RATE \{speed:\.3f\}' cannot be "
                                       r"formatted \(KeyError: 'speed'; fields given: \{rate_dps\}\)"):
        start(seq, closing(open_real_rig(replace(cfg, options={**cfg.options, "table_controller": bad}))), unit, "ok",
              None)
    fast_moves = {**tc, "positioning_rate_dps": 2000.0}
    with pytest.raises(RigLimitError, match=r"positioning_rate_dps 2000 °/s outside 0\.\.1000 °/s"):
        start(seq, closing(open_real_rig(replace(cfg, options={**cfg.options, "table_controller": fast_moves}))),
              unit, "ok", None)
    assert not [key for _, key, _ in lab.table_log if key != "mount"]  # nothing moved
