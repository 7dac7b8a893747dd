"""Tests of workbench.nav.compensate: the one place a calibration set meets raw samples."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from tests.nav.conftest import calibration_from_truth
from workbench.calset import CalibrationSet, Unit
from workbench.errors import AnalysisError, SessionError
from workbench.grades import draw_unit, load_spec
from workbench.nav.compensate import (ImuSamples, check_calibration, compensate, imu_samples, process_noise,
                                      white_density)

FS = 100.0


@pytest.fixture(scope="module")
def unit():
    return draw_unit(load_spec("industrial_mems"), seed=11)


def _frame(unit, n=500, seed=0):
    """Noise-free raw samples of ``unit`` for random true inputs over a temperature sweep."""
    rng = np.random.default_rng(seed)
    w = rng.normal(0, 1.0, (n, 3))
    f = rng.normal(0, 5.0, (n, 3)) + [0, 0, -9.8]
    m = rng.normal(0, 30.0, (n, 3))
    temp = np.linspace(-10.0, 50.0, n)
    raw = {"gyro": unit.gyro.apply(w, specific_force=f, temperature_c=temp),
           "accel": unit.accel.apply(f, temperature_c=temp), "mag": unit.mag.apply(m, temperature_c=temp)}
    df = pd.DataFrame({"t": np.arange(n) / FS, "step": 0, "temp": temp})
    for name, cols in (("gyro", "gx gy gz"), ("accel", "ax ay az"), ("mag", "mx my mz")):
        for i, c in enumerate(cols.split()):
            df[c] = raw[name][:, i]
    return df, w, f, m


def test_compensate_recovers_true_inputs_with_the_exact_model(unit):
    # exact model, noise-free data: only float round-off remains (the inverse is closed-form)
    df, w, f, m = _frame(unit)
    exact = calibration_from_truth(unit, errors={"gyro": (0, 0), "accel": (0, 0), "mag": (0, 0)})
    out = compensate(imu_samples(df, FS), exact)
    assert out.compensated == ("accel", "gyro", "mag")
    np.testing.assert_allclose(out.accel, f, atol=1e-9)
    np.testing.assert_allclose(out.gyro, w, atol=1e-9)  # needs the *compensated* accel for g-sensitivity
    np.testing.assert_allclose(out.mag, m, atol=1e-8)


def test_compensate_only_requested_triads_and_not_twice(unit):
    df, *_ = _frame(unit)
    cal = calibration_from_truth(unit)
    raw = imu_samples(df, FS)
    out = compensate(raw, cal, ("accel",))
    np.testing.assert_array_equal(out.gyro, raw.gyro)
    again = compensate(out, cal, ("accel",))
    np.testing.assert_array_equal(again.accel, out.accel)


def test_thermal_terms_need_the_temp_column(unit):
    df, *_ = _frame(unit)
    with pytest.raises(AnalysisError, match="no temp column"):
        compensate(imu_samples(df.drop(columns="temp"), FS), calibration_from_truth(unit))


def test_gap_in_samples_is_named(unit):
    df, *_ = _frame(unit)
    df = df.drop(index=range(100, 110)).reset_index(drop=True)
    with pytest.raises(SessionError, match=r"gap of 0\.11 s after t=0\.990"):
        imu_samples(df, FS, "run1")


def test_check_calibration_refuses_missing_wrong_and_incomplete_sets(unit):
    cal = calibration_from_truth(unit)
    with pytest.raises(AnalysisError, match="--calibration SET"):
        check_calibration(None, unit.serial, ("gyro",))
    with pytest.raises(AnalysisError, match="is for unit 'other'"):
        check_calibration(calibration_from_truth(unit, serial="other"), unit.serial, ("gyro",))
    warn = check_calibration(calibration_from_truth(unit, serial="other"), unit.serial, ("gyro",), force=True)
    assert len(warn) == 1 and "force=True" in warn[0]
    partial = CalibrationSet(Unit(unit.serial), {"gyro": cal.triads["gyro"]}, cal.noise)
    with pytest.raises(AnalysisError, match="no accel, mag triad"):
        check_calibration(partial, unit.serial, ("gyro", "accel", "mag"))
    assert check_calibration(cal, unit.serial, ("gyro", "accel", "mag")) == []


def test_process_noise_from_the_noise_block(unit):
    cal = calibration_from_truth(unit)
    pn = process_noise(cal, bias_correlation_s=400.0)
    np.testing.assert_allclose(pn.gyro_white, unit.gyro_noise.white)
    np.testing.assert_allclose(pn.accel_white, unit.accel_noise.white)
    # random walk density: rrw and B / sqrt(tau) in quadrature (closed form)
    expect = np.hypot(unit.gyro_noise.rrw, unit.gyro_noise.bias_instability / np.sqrt(400.0))
    np.testing.assert_allclose(pn.gyro_bias_rw, expect)
    no_arw = CalibrationSet(cal.unit, cal.triads, {"accel": cal.noise["accel"],
                                                   "gyro": {"bias_instability": [1e-5] * 3}})
    with pytest.raises(AnalysisError, match="noise.gyro.arw is not observed"):
        process_noise(no_arw)
    no_bi = CalibrationSet(cal.unit, cal.triads, {"accel": cal.noise["accel"], "gyro": {"arw": [1e-4] * 3}})
    assert any("gyro.rrw not observed" in n for n in process_noise(no_bi).notes)


def test_white_density_and_the_fallback_for_a_set_without_noise_terms(unit):
    rng = np.random.default_rng(5)
    n, dt, density = 20000, 0.01, np.array([1e-4, 2e-4, 5e-5])
    x = rng.normal(0.0, 1.0, (n, 3)) * density / np.sqrt(dt)
    ramp = np.outer(np.linspace(0.0, 1.0, n), [1.0, -2.0, 0.5]) ** 2  # a slowly varying input
    # MAD of 20000 second differences: relative sigma ~1 %; 5 % leaves 5 sigma
    np.testing.assert_allclose(white_density(x + ramp, dt), density, rtol=0.05)
    cal = calibration_from_truth(unit)
    bare = CalibrationSet(cal.unit, cal.triads, {})
    with pytest.raises(AnalysisError, match="arw is not observed"):
        process_noise(bare)
    samples = ImuSamples(np.arange(n) * dt, x, 2 * x, None, None, dt, (), "static run")
    pn = process_noise(bare, fallback=samples)
    np.testing.assert_allclose(pn.gyro_white, density, rtol=0.05)
    assert any("noise.accel.vrw not in the set: estimated from static run" in note for note in pn.notes)
