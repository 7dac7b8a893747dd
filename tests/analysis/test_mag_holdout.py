"""Truth-free quality of a hand-held magnetometer fit and its sigmas from the refits along time
(workbench/analysis/mag_holdout.py) on simulated points with a known calibration.

Points: a unit at random attitudes in a field of 48 µT, dip 60°; raw = S h + b with a known soft
iron S and hard iron b, white noise s = 0.2 µT per axis on the raw samples (after S: the
calibrated noise is white with std s to first order, S being near I); the accelerometer gives the
exact down direction.
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from workbench.analysis.mag_fit import MagFit
from workbench.analysis.mag_holdout import figures_of, halves, holdout_quality, jackknife_sigmas, point_values
from workbench.errors import AnalysisError

B, DIP, S_UT = 48.0, np.radians(60.0), 0.2
FIELD = B * np.array([np.cos(DIP), 0.0, np.sin(DIP)])
G = 9.81
SOFT = np.eye(3) + np.array([[0.04, 0.01, -0.01], [0.01, -0.02, 0.015], [-0.01, 0.015, 0.03]])
BIAS = np.array([15.0, -22.0, 7.0])


def _truth_fit(**kw) -> MagFit:
    base = dict(method="ellipsoid", bias=BIAS, bias_sigma=np.full(3, 0.1), soft_iron=SOFT,
                soft_iron_sigma=np.full((3, 3), 1e-3), field_norm_ut=B, field_norm_sigma=0.05, residual_rms_ut=S_UT,
                n_points=0, scale_fixed_by="det", dip=DIP, dip_sigma=1e-3, declination=None, declination_sigma=None,
                alignment=np.zeros(3), alignment_sigma=np.full(3, 1e-3))
    base.update(kw)
    return MagFit(**base)


def _points(n: int, seed: int, noise: float = S_UT):
    rng = np.random.default_rng(seed)
    att = Rotation.random(n, random_state=seed)
    h = att.inv().apply(FIELD)
    raw = h @ SOFT.T + BIAS + rng.normal(0.0, noise, (n, 3))
    accel = att.inv().apply([0.0, 0.0, -G])
    return raw, accel, np.sort(rng.uniform(0, 300, n))


def test_point_values_of_the_true_calibration_on_clean_points():
    """Noise-free: calibrated norm = B (deviation 0) and the field-to-down angle = 90° - dip = 30° (1e-12)."""
    raw, accel, _ = _points(300, 1, noise=0.0)
    norm, angle = point_values(_truth_fit(), raw, -accel / G)
    np.testing.assert_allclose(norm, 0.0, atol=1e-12)
    np.testing.assert_allclose(angle, np.pi / 2 - DIP, atol=1e-12)


def test_figures_of_the_true_calibration_are_the_noise_over_the_field():
    """The norm deviation is the radial noise over B (std s/B = 0.42 %), the angle's the noise across the
    field in the field-down plane over B (std s/B rad). N = 4000: the sample std has relative
    sigma 1/sqrt(2N) = 1.1 %; 4 sigma. Gravity mask: the angle is judged on the masked points only."""
    raw, accel, _ = _points(4000, 2)
    down = -accel / G
    norm_rms, angle_sd = figures_of(_truth_fit(), raw, down)
    tol = 4 / np.sqrt(2 * 4000)
    assert norm_rms == pytest.approx(S_UT / B, rel=tol)
    assert angle_sd == pytest.approx(S_UT / B, rel=tol)
    bad = np.zeros(4000, bool)
    bad[::2] = True
    down_wrong = down.copy()
    down_wrong[bad] = [1.0, 0.0, 0.0]  # points whose specific force is not gravity
    _, sd_masked = figures_of(_truth_fit(), raw, down_wrong, ~bad)
    assert sd_masked == pytest.approx(S_UT / B, rel=4 / np.sqrt(2 * 2000))


def test_held_out_figures_of_a_fixed_calibration_and_the_baseline():
    """A fitter that returns the true calibration: held out = in sample = s/B within the 4-sigma band
    of the halves (N/2 points each: 1/sqrt(N)). The plain ellipsoid fitted to the same points
    absorbs 9 of N degrees of freedom: its norm RMS is s/B (1 - 9/N) within the same band; its held-out
    one is s/B plus the error of 9 coefficients fitted on N/2 points, sqrt(1 + 9/(N/2)) ~ +0.2 %."""
    n = 4000
    raw, accel, t = _points(n, 3)
    truth = _truth_fit()
    q = holdout_quality(lambda sel: truth, truth, raw, accel, t, np.ones(n, bool))
    split, first, second = halves(t)
    assert q.split_t == pytest.approx(np.median(t)) and first.sum() == second.sum() == n // 2
    tol = 4 / np.sqrt(n)
    for value in (q.fit.norm_rms, q.fit.angle_spread, q.fit.norm_rms_held_out, q.fit.angle_spread_held_out):
        assert value == pytest.approx(S_UT / B, rel=tol)
    assert q.baseline is not None
    assert q.baseline.norm_rms == pytest.approx(S_UT / B, rel=tol)
    assert q.baseline.norm_rms_held_out == pytest.approx(S_UT / B, rel=tol)
    assert q.n_points == n and len(q.series["fit_norm"]) == n


@pytest.mark.parametrize("drift", [np.zeros(3), np.array([0.006, -0.004, 0.003])])  # µT/s
def test_hard_iron_move_between_the_halves(drift):
    """The halves' ellipsoids on points whose hard iron drifts in time by ``drift``: each half's hard iron is the
    mean over its half (the drift is linear in t), so they differ by drift x (mean t of the second half - of
    the first) = drift x 150 s (0.9, -0.6, 0.45 µT) within 4 of the halves' sigmas in quadrature (white noise
    alone: 0.2 µT over sqrt(1000 / 3) points per coefficient, ~0.016 µT measured; the hard iron's spread within a
    half, up to 1.3 µT, is a misfit the fit's residual scaling takes in: 0.06-0.2 µT); the summary says the field
    moved only when a component is over 4 sigma."""
    from workbench.analysis import mag_ellipsoid

    n = 2000
    raw, accel, t = _points(n, 5)
    raw = raw + np.outer(t, drift)
    fit = mag_ellipsoid.fit_ellipsoid(raw)
    q = holdout_quality(lambda sel: mag_ellipsoid.fit_ellipsoid(raw[sel]), fit, raw, accel, t, np.ones(n, bool))
    _, first, second = halves(t)
    expected = drift * (t[second].mean() - t[first].mean())
    assert np.all(np.abs(q.hard_iron_move - expected) < 4 * q.hard_iron_move_sigma)
    assert q.to_dict()["hard_iron_move_between_halves"]["ut"] == pytest.approx(list(q.hard_iron_move))
    (line,) = [x for x in q.lines("ellipsoid") if "second half minus the first" in x]
    assert ("moved during the record" in line) == bool(np.any(drift))


def test_jackknife_sigmas_floor_by_the_refits_and_keep_unobserved_ones():
    """A fitter whose hard iron x is the mean of per-point values that step by 1 µT half way through the
    record (a board whose hard iron moves): over 5 blocks the pseudo-values are (0, 0, 0.5, 1, 1) µT (variance
    0.25 µT²), so the jackknife sigma is sqrt(0.25 / 5) = 0.22 µT, the between-block one sqrt(0.25 - 5 * 0.1²)
    = 0.45 µT and the x sigma the largest of 0.1, 0.22 and 0.45 µT; y (constant) keeps its 0.1 µT; an unobserved
    sigma (NaN) stays NaN; a refit that fails leaves the sigmas as they are."""
    n = 1000
    x = np.r_[np.zeros(n // 2), np.ones(n // 2)]

    def fitter(keep):
        return _truth_fit(bias=BIAS + [x[keep].mean(), 0.0, 0.0], bias_sigma=np.array([0.1, 0.1, np.nan]))

    fit = jackknife_sigmas(fitter, fitter(np.ones(n, bool)), n, blocks=5)
    assert fit.bias_sigma[0] == pytest.approx(np.sqrt(0.25 - 5 * 0.1**2), rel=1e-6)
    assert fit.bias_sigma[1] == pytest.approx(0.1) and np.isnan(fit.bias_sigma[2])
    np.testing.assert_allclose(fit.soft_iron_sigma, 1e-3)
    assert fit.field_norm_sigma == pytest.approx(0.05) and fit.dip_sigma == pytest.approx(1e-3)

    def failing(keep):
        raise AnalysisError("degenerate")

    whole = fitter(np.ones(n, bool))
    assert jackknife_sigmas(failing, whole, n) is whole


@pytest.mark.parametrize("jump", [np.zeros(3), np.array([1.0, 0.0, -0.4])])  # µT, at the split
def test_held_out_norm_with_the_second_halfs_own_hard_iron(jump):
    """A hard iron that jumps by ``jump`` between the halves: refitted on the second half (the first half's soft
    iron kept), the held-out norm RMS is the noise's, s / B = 0.42 % (radial noise of the calibrated field; an RMS
    over 1000 points has a relative sigma of 1 / sqrt(2000) = 2.2 %, so within 10 %), where the first half's hard
    iron leaves |jump| / sqrt(3) / B = 1.3 % more (in quadrature: ~1.4 %); with no jump both are the noise's."""
    from workbench.analysis import mag_ellipsoid

    n = 2000
    raw, accel, t = _points(n, 6)
    _, first, second = halves(t)
    raw = raw + np.outer(second, jump)
    fit = mag_ellipsoid.fit_ellipsoid(raw)
    q = holdout_quality(lambda sel: mag_ellipsoid.fit_ellipsoid(raw[sel]), fit, raw, accel, t, np.ones(n, bool))
    assert abs(q.norm_rms_own_hard_iron / (S_UT / B) - 1.0) < 0.1
    if np.any(jump):
        assert q.fit.norm_rms_held_out > 2.5 * q.norm_rms_own_hard_iron
        (line,) = [x for x in q.lines("ellipsoid") if "second half minus the first" in x]
        assert f"own hard iron, the first half's soft iron kept: field-norm RMS {100 * q.norm_rms_own_hard_iron:.2f} %" in line
    else:
        assert abs(q.fit.norm_rms_held_out / q.norm_rms_own_hard_iron - 1.0) < 0.05
    move = q.to_dict()["hard_iron_move_between_halves"]
    assert move["field_norm_rms_pct_held_out_own_hard_iron"] == pytest.approx(100 * q.norm_rms_own_hard_iron)
