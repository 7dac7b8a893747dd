"""Turntable estimators on synthetic sessions built from closed-form truth + seeded white noise.

The sessions are made here (not by the simulator) so that the truth is exact and the noise
is white with a known sigma: the tests can then compare the reported 1-sigma with the
Cramér-Rao bound and with the scatter over seeds. Accuracy against the simulated rig is in
test_turntable_sim.py.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from workbench.analysis.turntable import fit_accel, fit_gyro_rate, fit_gyro_static
from workbench.calset import Unit
from workbench.earth import earth_rate_ned, rz
from workbench.errors import AnalysisError
from workbench.model import TriadModel
from workbench.sequence import mount_matrix
from workbench.session import Session, Site, StepRecord

SIX = ["x-up", "x-down", "y-up", "y-down", "z-up", "z-down"]
RATE_HZ = 100.0


def synth_session(steps, accel: TriadModel, gyro: TriadModel, sig_a: float, sig_g: float, seed: int,
                  latitude_deg: float = 40.8, azimuth_deg: float | None = 0.0) -> Session:
    """A session from ``steps`` = [(kind, mount, table_angle rad, table rate rad/s, duration s), ...].

    Truth: specific force = normal gravity (up) and angular rate = table rate + Earth rate,
    both rotated into the body; measured through the TriadModels plus white noise of
    ``sig_a`` (m/s^2) and ``sig_g`` (rad/s) per sample.
    """
    rng = np.random.default_rng(seed)
    site = Site(latitude_deg, 0.0, 0.0, azimuth_deg)
    az = np.radians(azimuth_deg or 0.0)
    w_ie = earth_rate_ned(site.latitude)
    frames, recs, t0 = [], [], 0.0
    for i, (kind, mount, angle, rate, dur) in enumerate(steps):
        m = mount if isinstance(mount, np.ndarray) else mount_matrix(mount)
        n = int(round(dur * RATE_HZ))
        t = t0 + np.arange(n) / RATE_HZ
        ang = angle + rate * (t - t0 + 0.5 / RATE_HZ)
        c_bn = rz((az + ang)[:, None]) * Rotation.from_matrix(m)  # body -> NED
        f = c_bn.inv().apply(np.array([0.0, 0.0, -site.gravity]))
        w = c_bn.inv().apply(w_ie) + (m.T @ np.array([0.0, 0.0, rate]))[None, :]
        a_meas = accel.apply(f) + sig_a * rng.standard_normal((n, 3))
        g_meas = gyro.apply(w, specific_force=f) + sig_g * rng.standard_normal((n, 3))
        df = pd.DataFrame({"t": t, "step": i, "gx": g_meas[:, 0], "gy": g_meas[:, 1], "gz": g_meas[:, 2],
                           "ax": a_meas[:, 0], "ay": a_meas[:, 1], "az": a_meas[:, 2],
                           "table_angle": ang, "table_rate": np.full(n, rate)})
        frames.append(df)
        label = mount if isinstance(mount, str) else "custom"
        recs.append(StepRecord(i, kind, t0, t0 + n / RATE_HZ, m, angle, rate, None, label))
        t0 += n / RATE_HZ
    return Session("synth", Unit("S1"), site, RATE_HZ, "test", recs, pd.concat(frames, ignore_index=True))


def truth_models(seed: int = 1):
    """An accel and a gyro model with MEMS-like errors (bias, M, and a gyro g-sensitivity)."""
    rng = np.random.default_rng(seed)
    acc = TriadModel(bias=rng.normal(0, 0.02, 3), scale_misalignment=rng.normal(0, 2e-3, (3, 3)))
    gyr = TriadModel(bias=rng.normal(0, 1e-3, 3), scale_misalignment=rng.normal(0, 2e-3, (3, 3)),
                     g_sensitivity=rng.normal(0, 2e-5, (3, 3)))
    return acc, gyr


def static_steps(mounts, dwell=10.0, angle=0.0):
    return [("static", m, angle, 0.0, dwell) for m in mounts]


def test_accel_six_positions_sigma_matches_cramer_rao():
    """6 positions, white noise: the reported sigma equals the closed-form CRB and the errors sit within it."""
    acc, gyr = truth_models()
    sig_a, dwell = 5e-3, 10.0
    s = synth_session(static_steps(SIX, dwell), acc, gyr, sig_a, 1e-4, seed=3)
    fit = fit_accel(s, nonlinearity="none", settle_s=0.0)
    n = dwell * RATE_HZ
    sm = sig_a / np.sqrt(n)  # sigma of one position mean
    g = s.site.gravity
    # Closed-form CRB of the 6-position design: a_jk = (y(+k) - y(-k)) / 2g -> sm / (g sqrt 2);
    # b_j = mean of the six positions -> sm / sqrt 6 (the pairs cancel the scale terms).
    crb_m, crb_b = sm / (g * np.sqrt(2)), sm / np.sqrt(6)
    # The white density is estimated from 6 x 1000 sample differences (1 % scatter):
    assert np.allclose(fit.notes["noise_white_density"], sig_a / np.sqrt(RATE_HZ), rtol=0.05)
    # A bias-wander floor F is added where the Allan variance at T/4 exceeds the white level by
    # two standard errors (2.3 % of white-noise axes): the reported sigma is then the CRB of the
    # model W/T + F. It is never below 0.8 x the white CRB, and at most 1.6 x the CRB of that
    # model (the Birge factor max(1, chi2/dof) with 6 dof).
    inflation = np.sqrt(1 + np.array(fit.notes["noise_floor"]) ** 2 / sm**2)
    assert np.all(fit.scale_misalignment_sigma > 0.8 * crb_m)
    assert np.all(fit.scale_misalignment_sigma < 1.6 * crb_m * inflation[:, None])
    # the bias also carries the floor itself (common to all positions, see _with_bias_floor)
    floor = np.array(fit.notes["noise_floor"])
    assert np.all(fit.bias_sigma > 0.8 * crb_b)
    assert np.all(fit.bias_sigma < np.sqrt((1.6 * crb_b * inflation) ** 2 + floor**2))
    assert np.all(np.abs(fit.scale_misalignment - acc.scale_misalignment) < 4 * fit.scale_misalignment_sigma)
    assert np.all(np.abs(fit.bias - acc.bias) < 4 * fit.bias_sigma)
    assert np.isnan(fit.nonlinearity_sigma).all()
    # residual after compensation: noise of a mean (sm ~ 1.6e-4 m/s^2), 5 sigma
    res = fit.residuals[[f"after_{a}" for a in "xyz"]].to_numpy()
    assert np.abs(res).max() < 5 * sm


def test_accel_sigma_agrees_with_scatter_over_seeds():
    """Monte Carlo: the spread of the bias estimate over 40 seeds agrees with the mean reported sigma."""
    acc, gyr = truth_models()
    errs, sigs = [], []
    for seed in range(40):
        s = synth_session(static_steps(SIX, 2.0), acc, gyr, 5e-3, 1e-4, seed=100 + seed)
        fit = fit_accel(s, nonlinearity="none", settle_s=0.0)
        errs.append(fit.bias - acc.bias)
        sigs.append(fit.bias_sigma)
    ratio = np.std(errs, axis=0) / np.mean(sigs, axis=0)
    # std of a 40-sample standard deviation ~ 1/sqrt(2*39) = 11 %; the Birge factor max(1, .)
    # biases the reported sigma up by ~10-20 %: accept 0.6..1.3.
    assert np.all(ratio > 0.6) and np.all(ratio < 1.3)


def test_accel_nonlinearity_from_24_positions():
    """Off-axis positions give 0.71 g inputs: nonlinearity becomes observable and is recovered."""
    acc, gyr = truth_models()
    acc = TriadModel(acc.bias, acc.scale_misalignment, nonlinearity=np.array([3e-4, -2e-4, 1e-4]))
    mounts = SIX + [Rotation.from_matrix(mount_matrix(m)) * Rotation.from_euler(ax, 45, degrees=True)
                    for m in ("x-up", "y-up", "z-up") for ax in "xyz"]
    mounts = [m if isinstance(m, str) else m.as_matrix() for m in mounts]
    s = synth_session(static_steps(mounts, 10.0), acc, gyr, 5e-3, 1e-4, seed=5)
    fit = fit_accel(s, nonlinearity="auto", settle_s=0.0)
    assert np.all(np.isfinite(fit.nonlinearity_sigma))
    assert np.all(np.abs(fit.nonlinearity - acc.nonlinearity) < 4 * fit.nonlinearity_sigma)
    six = synth_session(static_steps(SIX, 5.0), acc, gyr, 5e-3, 1e-4, seed=5)
    fit6 = fit_accel(six, nonlinearity="fit", settle_s=0.0)
    assert any("nonlinearity of the x axis not observable" in w for w in fit6.warnings)
    assert np.isnan(fit6.nonlinearity_sigma).all()


def test_mis_mounted_position_is_named():
    """A 3° fixture error in one of 18 positions is detected, named and excluded."""
    acc, gyr = truth_models()
    mounts = SIX + [Rotation.from_matrix(mount_matrix(m)) * Rotation.from_euler("z", a, degrees=True)
                    for m in ("x-up", "y-up", "z-up") for a in (45, 135, 225, 315)]
    mounts = [m if isinstance(m, str) else m.as_matrix() for m in mounts]
    s = synth_session(static_steps(mounts, 5.0), acc, gyr, 5e-3, 1e-4, seed=7)
    bad = 8
    # the unit is tilted 3° in its fixture, the record still says the nominal mount
    tilted = synth_session(static_steps([Rotation.from_euler("x", 3, degrees=True).as_matrix() @ mounts[bad]], 5.0),
                           acc, gyr, 5e-3, 1e-4, seed=8)
    sel = s.samples["step"] == bad
    for c in ("ax", "ay", "az"):
        s.samples.loc[sel, c] = tilted.samples[c].to_numpy()
    fit = fit_accel(s, nonlinearity="none", settle_s=0.0)
    assert fit.outliers == (bad,)
    assert any(f"step {bad} " in w and "excluded" in w for w in fit.warnings)
    assert not fit.residuals.loc[fit.residuals["step"] == bad, "used"].item()
    assert np.all(np.abs(fit.scale_misalignment - acc.scale_misalignment) < 4 * fit.scale_misalignment_sigma)


def test_three_positions_refused():
    acc, gyr = truth_models()
    s = synth_session(static_steps(["x-up", "y-up", "z-up"], 2.0), acc, gyr, 5e-3, 1e-4, seed=1)
    with pytest.raises(AnalysisError, match="3 usable static position"):
        fit_accel(s)


def test_static_step_with_motion_named():
    acc, gyr = truth_models()
    s = synth_session(static_steps(SIX + ["z-down"], 5.0), acc, gyr, 5e-3, 1e-4, seed=1)
    sel = (s.samples["step"] == 6) & (s.samples["t"] > s.steps[6].t_start + 2)
    s.samples.loc[sel, "gx"] += np.radians(2.0)  # someone bumps the table
    fit = fit_accel(s, settle_s=0.0)
    assert any("step 6 (z-down): not static" in w for w in fit.warnings)
    assert 6 not in fit.residuals["step"].tolist()


def test_missing_latitude_is_an_error():
    acc, gyr = truth_models()
    s = synth_session(static_steps(SIX, 2.0), acc, gyr, 5e-3, 1e-4, seed=1)
    s.site = Site(float("nan"))
    with pytest.raises(AnalysisError, match="latitude"):
        fit_accel(s)


def test_gyro_static_earth_rate_and_g_sensitivity():
    """Low-noise gyro: with the azimuth known the bias is recovered to the noise; without it a warning."""
    acc, gyr = truth_models()
    sig_g, dwell = 2e-6, 20.0  # rad/s per sample, a navigation-grade-like noise
    mounts = SIX + [Rotation.from_matrix(mount_matrix(m)) * Rotation.from_euler("z", 90, degrees=True)
                    for m in SIX]
    mounts = [m if isinstance(m, str) else m.as_matrix() for m in mounts]
    s = synth_session(static_steps(mounts, dwell), acc, gyr, 5e-3, sig_g, seed=11)
    fit = fit_gyro_static(s, settle_s=0.0, scale_misalignment=gyr.scale_misalignment)
    sm = sig_g / np.sqrt(dwell * RATE_HZ)
    # bias = mean of 12 positions (G terms cancel in the pairs): CRB sm / sqrt(12), Birge <= ~1.6,
    # times the floor's inflation (see the accelerometer CRB test)
    inflation = np.sqrt(1 + np.array(fit.notes["noise_floor"]) ** 2 / sm**2)
    assert np.all(fit.bias_sigma > 0.8 * sm / np.sqrt(12))
    floor = np.array(fit.notes["noise_floor"])
    assert np.all(fit.bias_sigma < np.sqrt((1.6 * sm / np.sqrt(12) * inflation) ** 2 + floor**2))
    assert np.all(np.abs(fit.bias - gyr.bias) < 4 * fit.bias_sigma)
    assert np.all(np.abs(fit.g_sensitivity - gyr.g_sensitivity) < 4 * fit.g_sensitivity_sigma)
    assert "modelled" in fit.notes["earth_rate"]
    s.site = Site(40.8, 0.0, 0.0, None)
    fit2 = fit_gyro_static(s, settle_s=0.0, scale_misalignment=gyr.scale_misalignment)
    assert any("Earth rate not modelled" in w for w in fit2.warnings)
    # the horizontal Earth rate (11 °/h here) does not fit bias + G f: the error is far above the
    # modelled fit's sigma, and the Birge factor widens the reported sigma to say so
    assert np.abs(fit2.bias - gyr.bias).max() > 20 * fit.bias_sigma.max()
    assert fit2.chi2_reduced > 10 and np.all(np.abs(fit2.bias - gyr.bias) < 4 * fit2.bias_sigma)


def rate_steps(rates_deg, revs=1, mounts=("x-up", "y-up", "z-up")):
    out = []
    for m in mounts:
        for r in rates_deg:
            for sign in (1, -1):
                rate = sign * np.radians(r)
                out.append(("rate", m, 0.0, rate, revs * 360.0 / r))
    return out


def test_gyro_rate_scale_misalignment_nonlinearity():
    acc, gyr = truth_models()
    gyr = TriadModel(gyr.bias, gyr.scale_misalignment, np.array([2e-4, -1e-4, 5e-5]), gyr.g_sensitivity)
    s = synth_session(rate_steps([30, 90, 180]), acc, gyr, 5e-3, 1e-3, seed=21)
    fit = fit_gyro_rate(s)
    assert np.all(np.abs(fit.scale_misalignment - gyr.scale_misalignment) < 4 * fit.scale_misalignment_sigma)
    assert np.all(np.abs(fit.nonlinearity - gyr.nonlinearity) < 4 * fit.nonlinearity_sigma)
    assert np.all(np.abs(fit.asymmetry) < 4 * fit.asymmetry_sigma)
    assert np.isnan(fit.bias_sigma).all()  # three 'up' mounts cannot separate bias from G
    two = synth_session(rate_steps([30, 90]), acc, gyr, 5e-3, 1e-3, seed=22)
    fit2 = fit_gyro_rate(two)
    assert any("not observable" in w and "nonlinearity" in w for w in fit2.warnings)
    assert np.isnan(fit2.nonlinearity_sigma).all()


def test_rate_step_shorter_than_a_revolution_named():
    acc, gyr = truth_models()
    steps = rate_steps([90]) + [("rate", "z-up", 0.0, np.radians(90), 2.0)]
    s = synth_session(steps, acc, gyr, 5e-3, 1e-3, seed=2)
    with pytest.raises(AnalysisError, match="step 6 .*less than one revolution"):
        fit_gyro_rate(s)


def test_mis_mount_in_six_positions_names_the_pair():
    """With six positions an up/down pair has identical deleted residuals: both are named, none dropped."""
    acc, gyr = truth_models()
    s = synth_session(static_steps(SIX, 5.0), acc, gyr, 5e-3, 1e-4, seed=7)
    tilted = synth_session(static_steps([Rotation.from_euler("x", 3, degrees=True).as_matrix() @ mount_matrix("y-up")],
                                        5.0), acc, gyr, 5e-3, 1e-4, seed=8)
    sel = s.samples["step"] == 2
    for c in ("ax", "ay", "az"):
        s.samples.loc[sel, c] = tilted.samples[c].to_numpy()
    fit = fit_accel(s, nonlinearity="none", settle_s=0.0)
    assert set(fit.outliers) == {2, 3}
    assert any("step 2 (y-up)" in w and "step 3 (y-down)" in w and "cannot tell" in w for w in fit.warnings)
    assert fit.residuals["used"].all()
