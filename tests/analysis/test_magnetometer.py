"""Magnetometer estimators on synthetic arrays: closed-form truth + seeded noise.

Truth (the issue's accuracy scenario): field 48 µT, dip 60°, declination 3°, hard iron
~10 µT, soft iron ~5 % off identity, white noise 0.3 µT per axis per point.
Heading errors are evaluated on a noise-free grid of attitudes (the calibration's own
error, not the noise of single samples) with the tilt taken from the true attitude.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from workbench.analysis import mag_ellipsoid, mag_fit2d
from workbench.analysis.mag_heading import evaluate_heading, heading
from workbench.analysis.mag_quality import sphere_coverage
from workbench.analysis.magnetometer import MagPoints, calibrate, triad_calibration
from workbench.calset import CalibrationSet, Unit
from workbench.errors import AnalysisError

F, DIP, DECL = 48.0, np.radians(60.0), np.radians(3.0)
H_NED = F * np.array([np.cos(DIP) * np.cos(DECL), np.cos(DIP) * np.sin(DECL), np.sin(DIP)])
HARD = np.array([8.0, -6.0, 4.5])  # µT, |b| ~ 11 µT
SOFT_SYM = np.eye(3) + np.array([[0.05, 0.02, -0.01], [0.02, -0.03, 0.015], [-0.01, 0.015, 0.04]])
ALIGN = Rotation.from_rotvec([0.004, -0.008, 0.010])  # rad, IMU -> magnetometer axes
SOFT = SOFT_SYM @ ALIGN.as_matrix()  # general soft iron: I + M = P U
NOISE = 0.3  # µT per axis per sample
STEP_SAMPLES = 100  # samples averaged per static turntable step (1 s at 100 Hz)
STEP_NOISE = NOISE / np.sqrt(STEP_SAMPLES)  # µT: the mean of 100 iid N(0, 0.3) samples is exactly N(0, 0.03)
G = 9.80665


def measure(att: Rotation, rng, soft=SOFT, noise=NOISE):
    """Raw magnetometer (µT) and accelerometer (m/s^2) for body->NED attitudes."""
    h = att.inv().apply(H_NED)
    m = h @ soft.T + HARD + rng.normal(0, noise, h.shape)
    acc = att.inv().apply([0.0, 0.0, -G]) + rng.normal(0, 0.003, h.shape)
    return m, acc


def turntable(tilt_deg: float, yaw_step_deg: float = 10.0, repeat: int = 1) -> Rotation:
    """Yaw sweeps at level and at ±tilt about x and about y (the default fixture)."""
    tilts = [(0, 0)] + ([(tilt_deg, 0), (-tilt_deg, 0), (0, tilt_deg), (0, -tilt_deg)] if tilt_deg else [])
    rots = [Rotation.from_euler("z", a, degrees=True) * Rotation.from_euler("xy", t, degrees=True)
            for t in tilts for a in np.arange(0, 360, yaw_step_deg) for _ in range(repeat)]
    return Rotation.concatenate(rots)


def grid_heading_rms(fit, att: Rotation, soft=SOFT, declination=DECL) -> float:
    """RMS heading error (°) of a fit on noise-free points at ``att``, true tilt, true declination
    (``declination=None``: the constant offset is removed)."""
    h = att.inv().apply(H_NED) @ soft.T + HARD
    down = att.inv().apply([0.0, 0.0, 1.0])
    return float(np.degrees(evaluate_heading(fit.compensate(h), down, att, declination, "table").rms))


FULL = Rotation.random(3000, random_state=7)


def test_heading_formula_matches_euler_yaw():
    att = Rotation.from_euler("ZYX", [[123.0, 20.0, -35.0], [-40.0, -10.0, 50.0]], degrees=True)
    h = att.inv().apply(H_NED)
    psi = heading(h, att.inv().apply([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(np.degrees(psi), [123.0 - 3.0, -40.0 - 3.0], atol=1e-9)  # magnetic = true - decl


def test_coverage_is_area_fraction():
    # uniform directions over the whole sphere fill every cell; a polar cap z > 0.5 is 25 % of the area
    u = Rotation.random(20000, random_state=1).apply([1.0, 0.0, 0.0])
    assert sphere_coverage(u) == 1.0
    cap = u[u[:, 2] > 0.5]
    assert sphere_coverage(cap) == pytest.approx(0.25, abs=1e-9)


def test_full_coverage_ellipsoid_meets_targets():
    rng = np.random.default_rng(11)
    m, _ = measure(FULL, rng, soft=SOFT_SYM)
    fit = mag_ellipsoid.fit_ellipsoid(m, field_norm_ut=F)
    # 3000 points, 0.3 µT noise: sigma(b) ~ 0.3 sqrt(3/3000) = 0.0095 µT; target 0.1 µT
    assert np.abs(fit.bias - HARD).max() < 0.1
    assert np.all(np.abs(fit.bias - HARD) < 4 * fit.bias_sigma)  # the reported sigma is honest
    assert fit.bias_sigma == pytest.approx(0.3 * np.sqrt(3 / 3000), rel=0.3)
    # soft iron: sigma ~ 0.3/48 sqrt(5/3000) ~ 2.6e-4; target 0.2 %
    assert np.abs(fit.soft_iron - SOFT_SYM).max() < 2e-3
    assert np.all(np.abs(fit.soft_iron - SOFT_SYM) < 4 * fit.soft_iron_sigma)
    assert grid_heading_rms(fit, turntable(45.0), SOFT_SYM) < 0.1


def test_ellipsoid_returns_the_symmetric_polar_factor():
    # an ellipsoid cannot see the rotation U of I+M = P U: the fit is P, the symmetric factor
    rng = np.random.default_rng(12)
    m, _ = measure(FULL, rng)
    fit = mag_ellipsoid.fit_ellipsoid(m, field_norm_ut=F)
    np.testing.assert_allclose(fit.soft_iron, fit.soft_iron.T, atol=1e-12)
    assert np.abs(fit.soft_iron - SOFT_SYM).max() < 2e-3
    assert fit.alignment is None


def test_det_convention_without_reference_norm():
    rng = np.random.default_rng(13)
    m, _ = measure(FULL, rng, soft=SOFT_SYM)
    fit = mag_ellipsoid.fit_ellipsoid(m)
    assert fit.scale_fixed_by == "det"
    assert np.linalg.det(fit.soft_iron) == pytest.approx(1.0, abs=1e-9)
    scale = np.cbrt(np.linalg.det(SOFT_SYM))
    # F and I+M trade a common scale: F_fit = 48 * det(A)^(1/3), A_fit = A / det(A)^(1/3)
    assert fit.field_norm_ut == pytest.approx(F * scale, abs=4 * fit.field_norm_sigma)
    assert np.abs(fit.soft_iron - SOFT_SYM / scale).max() < 2e-3
    assert any("det(I+M) = 1" in w for w in fit.warnings)


@pytest.mark.parametrize("method", ["attitude", "dip"])
def test_turntable_30deg_tilt(method):
    rng = np.random.default_rng(21)
    att = turntable(30.0)  # 5 tilts x 36 yaw steps, each the mean of 100 samples
    m, acc = measure(att, rng, noise=STEP_NOISE)
    cal = calibrate(MagPoints(m, acc, att, "NED"), method=method, field_norm_ut=F, declination=DECL)
    assert grid_heading_rms(cal.fit, turntable(30.0, 5.0)) < 0.2
    assert np.all(np.abs(cal.fit.bias - HARD) < 4 * cal.fit.bias_sigma)
    # the mag-to-IMU rotation is observed (attitude: sigma ~ 0.03/48/sqrt(180) ~ 0.05 mrad)
    assert np.all(np.abs(cal.fit.alignment - ALIGN.as_rotvec()) < 4 * cal.fit.alignment_sigma)
    assert np.degrees(cal.fit.dip) == pytest.approx(60.0, abs=4 * np.degrees(cal.fit.dip_sigma))


@pytest.mark.parametrize("method", ["attitude", "dip"])
def test_turntable_30deg_raw_samples(method):
    # raw 0.3 µT samples (e.g. continuous rotation) without noise-induced bias: the residuals are
    # first-order distances in µT, so a flat far-away ellipsoid gains nothing from the noise
    rng = np.random.default_rng(22)
    att = turntable(30.0, repeat=10)  # 1800 samples at 0.3 µT
    m, acc = measure(att, rng)
    cal = calibrate(MagPoints(m, acc, att, "NED"), method=method, field_norm_ut=F)
    assert grid_heading_rms(cal.fit, turntable(30.0, 5.0)) < 0.2
    assert np.all(np.abs(cal.fit.bias - HARD) < 4 * cal.fit.bias_sigma)


def test_turntable_30deg_plain_algebraic_is_worse():
    rng = np.random.default_rng(23)
    att = turntable(30.0)
    m, acc = measure(att, rng, noise=STEP_NOISE)
    cal = calibrate(MagPoints(m, acc, att, "NED"), field_norm_ut=F, declination=DECL)
    assert cal.fit.method == "attitude" and "table attitude" in cal.choice.reason
    ours, plain = grid_heading_rms(cal.fit, turntable(30.0, 5.0)), grid_heading_rms(cal.baseline, turntable(30.0, 5.0))
    assert ours < 0.2
    # the point: an unaided algebraic fit cannot see the 13 mrad (0.77°) rotation of I+M
    assert plain > 5 * ours


def test_turntable_15deg_tilt_with_table_angles():
    rng = np.random.default_rng(31)
    att = turntable(15.0)
    m, acc = measure(att, rng, noise=STEP_NOISE)
    cal = calibrate(MagPoints(m, acc, att, "NED"), field_norm_ut=F)
    assert cal.fit.method == "attitude"
    assert grid_heading_rms(cal.fit, turntable(15.0, 5.0)) < 0.2
    assert np.degrees(cal.fit.declination) == pytest.approx(3.0, abs=4 * np.degrees(cal.fit.declination_sigma))


def test_level_only_uses_2d_and_says_3d_is_not_observable():
    rng = np.random.default_rng(41)
    att = turntable(0.0, 5.0, repeat=10)  # 720 raw level samples at 0.3 µT
    m, acc = measure(att, rng)
    cal = calibrate(MagPoints(m, acc, att, "NED"), declination=DECL)
    fit = cal.fit
    assert fit.method == "2d" and "one plane" in cal.choice.reason
    # level data cannot separate the magnetometer's yaw misalignment (here 10 mrad) from the
    # declination: a constant heading offset, removed here as the lab removes it against a known azimuth
    assert grid_heading_rms(fit, turntable(0.0, 1.0), declination=None) < 0.5
    assert np.isnan(fit.bias_sigma[2]) and np.isnan(fit.soft_iron_sigma[2]).all()
    assert np.isnan(fit.soft_iron_sigma[:, 2]).all() and np.isnan(fit.field_norm_sigma)
    assert np.isfinite(fit.bias_sigma[:2]).all()
    assert any("not observable" in w for w in cal.warnings)
    # the calibration set carries the NaN sigmas as "not observed" (null in JSON)
    cs = CalibrationSet(unit=Unit("u1"), triads={"mag": triad_calibration(fit)})
    d = cs.to_dict()["mag"]
    assert d["bias_sigma"][2] is None and d["field_norm_ut_sigma"] is None


def test_2d_fit_reports_the_horizontal_scale_as_not_observed_and_passes_gate_and_exports():
    from workbench import plausibility
    from workbench.errors import ExportError
    from workbench.registry import exporters

    rng = np.random.default_rng(41)
    att = turntable(0.0, 5.0, repeat=10)
    m, acc = measure(att, rng)
    fit = calibrate(MagPoints(m, acc, att, "NED"), declination=DECL).fit
    # the common scale of the 2x2 block trades with the horizontal field: the convention (minor axis = 1)
    # sets the diagonal element nearest the minor axis, so exactly one horizontal diagonal reads not observed;
    # the other (the major / minor ratio) and the off-diagonal (the ellipse's tilt) are observed
    diag = fit.soft_iron_sigma[[0, 1], [0, 1]]
    assert np.isnan(diag).sum() == 1 and np.isfinite(fit.soft_iron_sigma[0, 1])
    assert any("common scale of the horizontal soft iron" in w for w in fit.warnings)
    cs = CalibrationSet(unit=Unit("u1"), triads={"mag": triad_calibration(fit)})
    assert plausibility.check(cs) == []  # not-observed entries are no failure
    for name, module in exporters().items():
        try:
            out = module.export(cs)  # every format writes a set with not-observed entries, never a bare nan
        except ExportError as exc:
            assert "no noise block" in str(exc), name  # Kalibr's format is noise only
            continue
        assert out.text and not re.search(r"\b(nan|NaN)\b", out.text), name  # (C's NAN macro is math.h's)


def test_paper_004_minmax_recipe_on_level_data():
    # noise-free level data: eq. 10-18 recover the 2x2 distortion up to the paper's scaling
    att = turntable(0.0, 1.0)
    h = att.inv().apply(H_NED)
    a2 = mag_fit2d.soft_iron_2d(np.radians(25.0), 1.08)
    soft = np.eye(3)
    soft[:2, :2] = a2
    m = h @ soft.T + HARD
    fit = mag_fit2d.fit_2d_minmax(m)
    assert np.abs(fit.soft_iron[:2, :2] - a2).max() < 2e-3  # 1° sampling of the extremes
    assert np.abs(fit.bias[:2] - (HARD[:2] + soft[:2, 2] * h[0, 2])).max() < 0.05


def test_robust_fit_with_spikes_stays_within_twice_clean_error():
    rng = np.random.default_rng(51)
    m, _ = measure(FULL, rng, soft=SOFT_SYM)
    clean = mag_ellipsoid.fit_ellipsoid(m, field_norm_ut=F, robust=True)
    spiked = m.copy()
    k = rng.choice(len(m), size=len(m) // 20, replace=False)  # 5 % of the points
    direction = rng.normal(size=(len(k), 3))
    spiked[k] += direction / np.linalg.norm(direction, axis=1, keepdims=True) * rng.uniform(20, 40, (len(k), 1))
    robust = mag_ellipsoid.fit_ellipsoid(spiked, field_norm_ut=F, robust=True)
    plain = mag_ellipsoid.fit_ellipsoid(spiked, field_norm_ut=F)
    # clean-data error scale: the expected |b error| = |sigma| (not one lucky realisation)
    clean_err = max(np.linalg.norm(clean.bias - HARD), np.linalg.norm(clean.bias_sigma))
    assert np.linalg.norm(robust.bias - HARD) < 2 * clean_err
    assert np.abs(robust.soft_iron - SOFT_SYM).max() < 2 * max(np.abs(clean.soft_iron - SOFT_SYM).max(),
                                                               np.nanmax(clean.soft_iron_sigma))
    assert np.linalg.norm(plain.bias - HARD) > 2 * clean_err  # the spikes do matter without it
    assert any("outliers" in w for w in robust.warnings)


def test_limited_coverage_warns_for_unaided_ellipsoid():
    rng = np.random.default_rng(61)
    att = turntable(15.0, repeat=3)
    m, _ = measure(att, rng)
    cal = calibrate(MagPoints(m), method="ellipsoid")
    assert any("cannot support an unaided ellipsoid" in w for w in cal.warnings)
    auto = calibrate(MagPoints(m))  # no accel, no attitude, cap: hard iron only
    assert auto.fit.method == "sphere" and np.isnan(auto.fit.soft_iron_sigma).all()


# -- bad input ---------------------------------------------------------------------------
def _full_points(n=400, seed=71, scale=1.0):
    rng = np.random.default_rng(seed)
    m, acc = measure(Rotation.random(n, random_state=seed), rng)
    return m * scale, acc


def test_too_few_points():
    m, _ = _full_points(10)
    with pytest.raises(AnalysisError, match="10 points"):
        calibrate(MagPoints(m), method="ellipsoid")


def test_coplanar_points_for_3d_fit():
    rng = np.random.default_rng(72)
    m, acc = measure(turntable(0.0, 5.0), rng)
    with pytest.raises(AnalysisError, match="one plane"):
        calibrate(MagPoints(m, acc), method="ellipsoid")


def test_nan_samples():
    m, _ = _full_points()
    m[17, 1] = np.nan
    with pytest.raises(AnalysisError, match="row 17"):
        calibrate(MagPoints(m))


def test_gauss_where_ut_declared():
    m, _ = _full_points(scale=0.01)  # 48 µT written as 0.48 gauss
    with pytest.raises(AnalysisError, match="gauss"):
        calibrate(MagPoints(m))


def test_field_norm_outside_geomagnetic_range_warns():
    m, _ = _full_points(scale=8.0 / 48.0)  # an 8 µT "field": no unit makes it geomagnetic
    cal = calibrate(MagPoints(m), method="ellipsoid")
    assert any("outside the geomagnetic range" in w for w in cal.warnings)


def test_unknown_method():
    m, _ = _full_points()
    with pytest.raises(AnalysisError, match="unknown magnetometer method"):
        calibrate(MagPoints(m), method="magic")


def test_dip_fit_needs_accelerometer():
    m, _ = _full_points()
    with pytest.raises(AnalysisError, match="accelerometer"):
        calibrate(MagPoints(m), method="dip")


# -- geomagnetic reference -----------------------------------------------------------------
def test_igrf_reference_field_is_plausible_and_checks_the_fit():
    from datetime import datetime

    from workbench.analysis.mag_reference import ReferenceField, compare, igrf_field

    # plausibility against the known field of southern Italy (magnetic charts: ~46-47 µT,
    # inclination ~56-58°, declination ~3-5° E); catches unit (nT/µT) and sign/axis slips
    ref = igrf_field(40.8, 14.25, 30.0, datetime(2026, 11, 22))
    assert ref.norm_ut == pytest.approx(46.5, abs=1.0)
    assert np.degrees(ref.dip) == pytest.approx(57.0, abs=1.5)
    assert np.degrees(ref.declination) == pytest.approx(4.0, abs=1.5)
    rng = np.random.default_rng(81)
    att = turntable(30.0)
    m, acc = measure(att, rng, noise=STEP_NOISE)
    fit = calibrate(MagPoints(m, acc, att, "NED")).fit  # truth 48 µT, dip 60°: dip is 2.7° off IGRF
    notes = compare(fit, ref)
    assert any("dip" in n for n in notes) and not any("norm" in n for n in notes)  # 48 vs 46.7: within 5 %
    assert compare(fit, ReferenceField(48.0, DIP, DECL)) == []


def test_large_hard_iron_is_not_mistaken_for_a_unit_slip():
    m, _ = _full_points()
    cal = calibrate(MagPoints(m + np.array([250.0, 0.0, 0.0])), method="ellipsoid", field_norm_ut=F)
    assert abs(cal.fit.bias[0] - 258.0) < 0.2  # 250 µT added to the 8 µT hard iron
