"""Thermal procedure end to end on the virtual lab: soak and ramp profiles against the unit's truth.

Simulation settings (stated, to keep the runtime small): 10 Hz samples and a unit thermal
time constant of 120 s (soak) / 60 s (ramp) instead of the grade's 100 Hz and 600 s; the
temperature curves, noise densities and the 0.05 °/s up/down gyro hysteresis are the grade's.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from procedures import thermal as proc
from workbench.grades import Hysteresis, draw_unit, load_spec
from workbench.registry import exporter
from workbench.jobs import simulate

DEG = np.pi / 180
MG = 9.80665e-3
GAP = 0.05 * DEG  # rad/s, warming-minus-cooling gyro bias difference (play operator, 2 °C wide)
SPEC = load_spec("industrial_mems")


def unit(seed: int, tau: float):
    truth = draw_unit(SPEC, seed)
    return replace(truth, sample_rate_hz=10.0, thermal_time_constant_s=tau,
                   gyro_hysteresis=Hysteresis(np.full(3, GAP), 2.0))


@pytest.fixture(scope="module")
def soak_run():
    seq = proc.sequence(SPEC, t_min_c=-40.0, t_max_c=85.0, step_c=15.0, return_sweep=True, dwell_s=10.0)
    session, truth = simulate(seq, unit(1, 120.0), 1)
    return proc.analyze(session), truth


def true_bias(truth, triad: str, temps: np.ndarray, direction: int) -> np.ndarray:
    m = getattr(truth, triad)
    h = truth.hysteresis_of(triad)
    return m.bias + m.thermal.bias_shift(temps) + (0.0 if h is None else 0.5 * direction * h.gap)


def test_soak_sweep_compensation_residuals(soak_run):
    result, truth = soak_run
    r = result.payload
    temps = np.linspace(r.t_min_c, r.t_max_c, 126)
    # tolerances of the issue: gyro 0.01 °/s, accel 1 mg after compensation, per branch
    for triad, tol in (("gyro", 0.01 * DEG), ("accel", 1.0 * MG)):
        fit = r.fits[f"{triad}.bias"]
        assert fit.order == 3
        assert np.all(fit.cv_rms_chosen < tol)  # held-out soak temperatures
        for d in (1, -1):
            err = fit.predict(temps, np.full(temps.size, d)) - true_bias(truth, triad, temps, d)
            assert np.all(np.sqrt(np.mean(err**2, axis=0)) < tol), (triad, d)


def test_soak_sweep_hysteresis_and_scale(soak_run):
    result, truth = soak_run
    r = result.payload
    g = r.fits["gyro.bias"]
    assert np.all(np.abs(g.hysteresis - GAP) < 0.2 * GAP) and g.hysteresis_modelled.all()
    s = r.fits["accel.scale"]
    temps = np.linspace(r.t_min_c, r.t_max_c, 126)
    true = np.diag(truth.accel.scale_misalignment) + truth.accel.thermal.scale_shift(temps)
    # one soak's scale factor: ~40 ppm (six 10 s positions, 0.01° positioning error); the fit of
    # 19 soaks averages it to ~40/sqrt(19/3) = 16 ppm: 4 sigma = 64 ppm
    assert np.all(np.sqrt(np.mean((s.predict(temps) - true) ** 2, axis=0)) < 64e-6)


def test_soak_sweep_calibration_set_and_outputs(soak_run):
    result, truth = soak_run
    cal = result.calibration
    assert cal.to_json()  # schema-valid
    th = cal.model("gyro").thermal
    assert th.t_ref_c == 25.0 and th.bias_poly.shape == (3, 4) and np.all(th.bias_poly[:, 0] == 0)
    sig = cal.triads["gyro"].sigma_of("thermal.bias_poly")
    assert np.all(np.isfinite(sig[:, 1:]) & (sig[:, 1:] > 0))
    assert cal.triads["accel"].thermal_range_c[0] < -39 and cal.triads["accel"].thermal_range_c[1] > 84
    figs = proc.figures(result)
    assert {"gyro_bias_fit", "gyro_bias_residuals", "gyro_bias_order"} <= set(figs)
    # the set the exports carry, against the truth: the bias at t_ref (mid-branch) of each triad within
    # 4 of its own 1-sigma (the soak means' noise propagated through the fit)
    for triad in ("gyro", "accel"):
        ref = true_bias(truth, triad, np.array([th.t_ref_c]), 0)[0]
        est, sig = cal.model(triad).bias, cal.triads[triad].sigma_of("bias")
        assert np.all(np.abs(est - ref) < 4 * sig), (triad, (est - ref) / sig)
    for fmt in ("px4", "ardupilot", "c-header"):
        exp = exporter(fmt).export(cal)
        assert exp.text
    assert any("scale-factor temperature polynomial" in d for d in exporter("px4").export(cal).dropped)
    assert any("hysteresis" in d for d in exporter("ardupilot").export(cal).dropped)


def test_ramp_profile_direct_fit():
    seq = proc.sequence(SPEC, profile="ramp", t_min_c=-40.0, t_max_c=85.0, ramp_c_per_min=2.0, return_sweep=True)
    session, truth = simulate(seq, unit(2, 60.0), 3)
    result = proc.analyze(session)
    r = result.payload
    assert r.source == "ramp"
    g = r.fits["gyro.bias"]
    # no reference set: the static z-down "bias" includes the g-sensitivity G f (constant)
    f = np.array([0.0, 0.0, -session.site.gravity])
    temps = np.linspace(r.t_min_c + 5, r.t_max_c - 5, 100)  # the fit's range, away from the turn-around
    for d in (1, -1):
        ref = true_bias(truth, "gyro", temps, d) + truth.gyro.g_sensitivity @ f
        err = g.predict(temps, np.full(temps.size, d)) - ref
        assert np.all(np.sqrt(np.mean(err**2, axis=0)) < 0.01 * DEG)
    assert np.all(np.abs(g.hysteresis - GAP) < 0.2 * GAP)
    assert g.order == 3
