"""Imperfections of the virtual IMU (workbench.sim.imperfections) measured against their settings."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.errors import WorkbenchError
from workbench.grades import draw_unit, load_spec
from workbench.sim.imperfections import Imperfections
from workbench.sim.sensor import VirtualIMU
from workbench.units import factor

SPEC = load_spec("industrial_mems")
TRUTH = draw_unit(SPEC, 3)
DPH = factor("deg/h")


def _static(imu: VirtualIMU, seconds: float, temp_c: float = 25.0, rate=(0.0, 0.0, 0.0)):
    n = int(round(seconds * TRUTH.sample_rate_hz))
    omega = np.tile(np.asarray(rate, float), (n, 1))
    f = np.tile([0.0, 0.0, -9.81], (n, 1))
    m = np.tile([20.0, 0.0, 40.0], (n, 1)) if "mag" in TRUTH.triads else None
    return imp_out(imu.measure(omega, f, m, np.full(n, temp_c)))


def imp_out(out):
    return out["gyro"], out["accel"]


def test_off_by_default_and_the_noise_streams_are_kept():
    a = _static(VirtualIMU(TRUTH, 5), 2.0)
    b = _static(VirtualIMU(TRUTH, 5, Imperfections()), 2.0)
    np.testing.assert_array_equal(a[0], b[0])
    # a turn-on bias only adds a constant: the noise is the same sample for sample
    c = _static(VirtualIMU(TRUTH, 5, Imperfections(turn_on_bias={"gyro": 50 * DPH})), 2.0)
    d = c[0] - a[0]
    np.testing.assert_allclose(d - d[0], 0.0, atol=1e-12)
    with pytest.raises(WorkbenchError, match="unknown triad"):
        Imperfections(turn_on_bias={"gyros": 1.0})


def test_warm_up_transient_decays_with_its_time_constant():
    # 300 °/h at power-on decaying with tau = 120 s, industrial MEMS (ARW 0.2 °/sqrt(h), BI 8 °/h).
    # The mean of 0-60 s minus that of 540-600 s is b_w tau/60 (1 - e^-0.5) - (e^-4.5 - e^-5) ~ 236 °/h;
    # noise of that difference: ARW over 60 s (1.5 °/h per window) and the flicker's wander (~BI): 4 x 10 °/h.
    imp = Imperfections(warm_up_bias={"gyro": [300 * DPH] * 3}, warm_up_tau_s=120.0)
    g = _static(VirtualIMU(TRUTH, 8, imp), 600.0)[0]
    g0 = _static(VirtualIMU(TRUTH, 8), 600.0)[0]  # the same noise without the transient
    n = int(60 * TRUTH.sample_rate_hz)
    tau = 120.0
    expect = 300 * (tau / 60) * ((1 - np.exp(-0.5)) - (np.exp(-4.5) - np.exp(-5.0)))
    diff = ((g[:n].mean(0) - g[-n:].mean(0)) - (g0[:n].mean(0) - g0[-n:].mean(0))) / DPH
    np.testing.assert_allclose(diff, expect, rtol=1e-3)  # same noise: the transient alone, to the sampling
    raw = (g[:n].mean(0) - g[-n:].mean(0)) / DPH
    assert np.all(np.abs(raw - expect) < 40.0)


def test_turn_on_repeatability_of_bias_and_scale():
    # 120 power-ons (seeds) of 0.2 s, each against the same seed without imperfections (the noise is the
    # same sample for sample, see above): the difference is this power-on's bias offset, and at 1 rad/s
    # about z its scale-factor offset too. The std of 120 draws is within 26 % (4 sigma of a std
    # estimate, relative sigma 1/sqrt(2 x 119)) of the setting.
    sb, ss = 20 * DPH, 1e-3
    imp = Imperfections(turn_on_bias={"gyro": [sb] * 3}, turn_on_scale={"gyro": ss})
    bias, scale = [], []
    for s in range(120):
        d0 = _static(VirtualIMU(TRUTH, s, imp), 0.2)[0].mean(0) - _static(VirtualIMU(TRUTH, s), 0.2)[0].mean(0)
        d1 = (_static(VirtualIMU(TRUTH, s, imp), 0.2, rate=(0, 0, 1.0))[0].mean(0)
              - _static(VirtualIMU(TRUTH, s), 0.2, rate=(0, 0, 1.0))[0].mean(0))
        bias.append(d0)
        scale.append(d1[2] - d0[2])
    np.testing.assert_allclose(np.std(bias, axis=0, ddof=1), sb, rtol=0.26)
    # the model's own response to 1 rad/s is (1 + M_zz): the offset scales it, ~1 to 1e-3
    assert np.std(scale, ddof=1) == pytest.approx(ss, rel=0.26)
    assert abs(np.mean(bias)) < 4 * sb / np.sqrt(360)


def test_noise_grows_with_temperature():
    # c = 1 %/°C, +40 °C: 1.4x the noise; std of 20 000 samples known to 0.5 %
    imp = Imperfections(noise_temp_coeff={"accel": 0.01})
    cold = _static(VirtualIMU(TRUTH, 9, imp), 200.0, temp_c=25.0)[1]
    hot = _static(VirtualIMU(TRUTH, 9, imp), 200.0, temp_c=65.0)[1]
    ratio = np.diff(hot, axis=0).std(axis=0) / np.diff(cold, axis=0).std(axis=0)
    np.testing.assert_allclose(ratio, 1.4, rtol=0.03)


def test_the_simulated_rig_takes_the_imperfections():
    # the rig passes them to its virtual IMU (workbench.jobs.simulate passes them to the rig)
    from workbench.rigconfig import load_rig_config
    from workbench.sim.rig import SimRig

    cfg = load_rig_config("sim")
    a = SimRig(cfg, TRUTH, 2).advance(np.zeros(300))
    b = SimRig(cfg, TRUTH, 2, imperfections=Imperfections(turn_on_bias={"gyro": 100 * DPH})).advance(np.zeros(300))
    d = b[["gx", "gy", "gz"]].to_numpy() - a[["gx", "gy", "gz"]].to_numpy()
    assert np.all(d.std(axis=0) < 1e-12) and np.abs(d[0]).max() > 1 * DPH


def test_scale_factor_drift_within_a_run():
    # 1 rad/s about z for 600 s; with and without the drift the noise is the same sample for sample, so
    # the difference is r t (the model's output, ~1 rad/s) exactly: its slope over 0-600 s is this
    # power-on's rate r. 120 power-ons: the std of r within 26 % (4 sigma of a std from 120 draws) of
    # the setting; off (the default) the samples are unchanged.
    sd = 200e-6 / 3600.0  # 200 ppm/h
    imp = Imperfections(scale_drift={"gyro": sd})
    np.testing.assert_array_equal(_static(VirtualIMU(TRUTH, 4, Imperfections()), 5.0, rate=(0, 0, 1.0))[0],
                                  _static(VirtualIMU(TRUTH, 4), 5.0, rate=(0, 0, 1.0))[0])
    n = int(600 * TRUTH.sample_rate_hz)
    t = np.arange(n) / TRUTH.sample_rate_hz
    rates = []
    for s in range(120):
        d = (_static(VirtualIMU(TRUTH, s, imp), 600.0, rate=(0, 0, 1.0))[0][:, 2]
             - _static(VirtualIMU(TRUTH, s), 600.0, rate=(0, 0, 1.0))[0][:, 2])
        rates.append(np.polyfit(t, d, 1)[0])
        if s == 0:  # the drawn rate itself, to rounding (the model output is 1 rad/s within 1 %)
            r0 = imp.draw(tuple(TRUTH.triads), 0)[2][2]
            assert rates[0] == pytest.approx(r0, rel=0.02)
    assert np.std(rates, ddof=1) == pytest.approx(sd, rel=0.26)


def test_grade_block_sets_the_defaults():
    from workbench.grade_types import SpecError

    spec = load_spec("industrial_mems")
    imp = Imperfections.from_spec(spec, ["turn_on"])
    # fixture: turn_on_bias_mg 5, turn_on_scale_ppm 1500 (accel); turn_on_bias_deg_per_h 200 (gyro)
    np.testing.assert_allclose(imp.turn_on_bias["accel"], 5 * factor("mg"))
    np.testing.assert_allclose(imp.turn_on_scale["accel"], 1500e-6)
    np.testing.assert_allclose(imp.turn_on_bias["gyro"], 200 * DPH)
    assert not imp.warm_up_bias and not imp.scale_drift and imp.warm_up_tau_s == 300.0
    every = Imperfections.from_spec(spec, "all")
    np.testing.assert_allclose(every.scale_drift["gyro"], 200e-6 / 3600.0)
    assert not Imperfections.from_spec(spec, "off").unit
    with pytest.raises(WorkbenchError, match="unknown 'warmup'"):
        Imperfections.from_spec(spec, ["warmup"])
    with pytest.raises(WorkbenchError, match="has no 'warm_up'"):
        Imperfections.from_spec(load_spec("hg1700"), ["warm_up"])
    import yaml
    from workbench.grade_fixtures import _parse_spec

    data = yaml.safe_load(spec.path.read_text())
    data["imperfections"]["accel"]["turn_on_bias_deg_per_h"] = 1.0
    with pytest.raises(SpecError, match=r"imperfections\.accel\.turn_on_bias_deg_per_h: unit 'deg_per_h'"):
        _parse_spec(data, spec.path)


def test_procedure_options_switch_them_on(tmp_path):
    # `-o imperfections=turn_on` through workbench.jobs.record_procedure: the gyro samples differ from the
    # same seed without by this power-on's offset b_on + dM_on y (the noise is the same); |dM_on y| is
    # below 4 x 3000 ppm x 0.2 °/s (largest |y| at rest: bias 360 °/h x 4 + Earth rate).
    import procedures.multiposition as mp
    from workbench.jobs import open_rig, record_procedure
    from workbench.options import option_rows
    from workbench.rigconfig import load_rig_config
    from dataclasses import replace

    cfg = load_rig_config("sim")
    opts = {"positions": 6, "dwell_s": 2.0}
    off = record_procedure(mp, SPEC, TRUTH, cfg, 7, None, opts)
    on = record_procedure(mp, SPEC, TRUTH, cfg, 7, tmp_path / "s", {**opts, "imperfections": "turn_on"})
    d = on.samples[["gx", "gy", "gz"]].to_numpy() - off.samples[["gx", "gy", "gz"]].to_numpy()
    b_on = Imperfections.from_spec(SPEC, ["turn_on"]).draw(tuple(TRUTH.triads), 7)[0][:3]
    assert np.all(np.abs(d - b_on) < 4 * 3000e-6 * np.radians(0.2))
    assert np.abs(b_on).max() > 20 * DPH  # a real offset (1-sigma 200 °/h), not a zero
    import json
    assert json.loads((tmp_path / "s" / "session.json").read_text())["rig_options"] == {"imperfections": "turn_on"}
    assert {"imperfections", "table_wobble_deg"} <= {r["name"] for r in option_rows(mp)}
    with pytest.raises(WorkbenchError, match="simulated rig only"):
        open_rig(replace(cfg, driver="acme"), TRUTH, 0, imperfections=Imperfections(turn_on_bias={"gyro": 1.0}))


def test_resume_switches_the_same_imperfections_on(tmp_path):
    # a recording with -o imperfections=all interrupted after 2 of 6 steps and resumed (the manifest's
    # rig_options) gives the same samples as one recorded without interruption: the resumed part has the
    # same power-on draws and the warm-up / drift clock continues (VirtualIMU state "k")
    import procedures.multiposition as mp
    from workbench.jobs import record_procedure, resume_procedure
    from workbench.rigconfig import load_rig_config

    class Stop(Exception):
        pass

    def progress(i, n, rec):
        if i + 1 == 2:
            raise Stop

    cfg = load_rig_config("sim")
    opts = {"positions": 6, "dwell_s": 2.0, "imperfections": "all"}
    whole = record_procedure(mp, SPEC, TRUTH, cfg, 9, tmp_path / "whole", opts)
    with pytest.raises(Stop):
        record_procedure(mp, SPEC, TRUTH, cfg, 9, tmp_path / "cut", opts, progress=progress)
    resumed = resume_procedure(tmp_path / "cut")
    cols = ["gx", "gy", "gz", "ax", "ay", "az"]
    np.testing.assert_allclose(resumed.samples[cols].to_numpy(), whole.samples[cols].to_numpy(), rtol=0, atol=1e-12)
    plain = record_procedure(mp, SPEC, TRUTH, cfg, 9, None, {"positions": 6, "dwell_s": 2.0})
    assert np.abs(plain.samples[cols].to_numpy() - whole.samples[cols].to_numpy()).max() > 1e-3  # they are on
