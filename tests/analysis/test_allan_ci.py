"""Noise identification, Greenhall EDF and chi-squared interval coverage.

References: allantools.ci.edf_greenhall (same algorithm; it switches to the paper's large-J
tables where this implementation evaluates the sum on a rescaled problem), and an exact
expected AVAR for linear-filter noise (derivation in ``_true_avar``).
"""

import allantools.ci as aci
import numpy as np
import pytest
from scipy.signal import fftconvolve

from workbench.analysis.allan import deviation, phase
from workbench.analysis.allan_ci import (alpha_from_slope, confidence, detrend_quadratic, edf_greenhall,
                                         edf_greenhall_many, identify, round_alpha)
from workbench.sim.powerlaw import kasdin_response


@pytest.mark.parametrize("d,modified,alphas,ms", [
    (2, False, (2, 1, 0, -1, -2), (1, 2, 4, 8, 16, 32)),
    (2, True, (2, 1, 0, -1, -2), (1, 2, 4, 8, 16, 32)),
    (3, False, (2, 1, 0, -1, -2, -3), (1, 2, 4, 8, 16, 24)),
])
def test_edf_equals_allantools_where_both_sum_directly(d, modified, alphas, ms):
    # (d+1) m <= 100 terms: allantools evaluates Greenhall's BasicSum directly, as we do -> same numbers
    for alpha in alphas:
        for m in ms:
            for n in (1_000, 100_000):
                ref = aci.edf_greenhall(alpha=alpha, d=d, m=m, N=n, overlapping=True, modified=modified)
                assert edf_greenhall(alpha, d, m, n, True, modified) == pytest.approx(ref, rel=1e-9)


def test_edf_close_to_allantools_tables_for_long_sums():
    # beyond 100 terms allantools uses the paper's asymptotic tables (3 significant digits, and
    # an asymptote in r = M/S); the rescaled direct sum agrees to a few per cent (measured <= 6.2 %)
    for alpha in (1, 0, -1, -2):
        for m in (64, 512, 4096):
            ref = aci.edf_greenhall(alpha=alpha, d=2, m=m, N=1_000_000, overlapping=True, modified=False)
            assert edf_greenhall(alpha, 2, m, 1_000_000) == pytest.approx(ref, rel=0.07)


def _true_avar(h: np.ndarray, n: int, ms: np.ndarray) -> np.ndarray:
    """Exact expected overlapping AVAR (unit white drive, dt = 1) of y = h * w over n samples.

    With g = cumsum(h) the phase is x_k = sum_j g(k-1-j) w_j, so the second difference
    D_i = x[i+2m] - 2 x[i+m] + x[i] = sum_j w_j e(i+2m-1-j), e(u) = g(u) - 2 g(u-m) + g(u-2m),
    and E[D_i^2] = sum_{u <= i+2m-1} e(u)^2. AVAR = mean_i E[D_i^2] / (2 m^2).
    """
    g = np.cumsum(h[:n])
    out = []
    for m in ms:
        gp = np.concatenate((np.zeros(2 * m), g))
        e = gp[2 * m:] - 2 * gp[m:-m] + gp[:-2 * m]
        c = np.cumsum(e ** 2)
        i = np.arange(n + 1 - 2 * m)
        out.append(np.mean(c[i + 2 * m - 1]) / (2.0 * m * m))
    return np.array(out)


@pytest.mark.parametrize("a,alpha_true", [(0.0, 0), (1.0, -1), (2.0, -2)])
def test_ci95_coverage_monte_carlo(a, alpha_true):
    # white (a=0), flicker (a=1) and random-walk (a=2) rate noise; 300 records of 4096 samples as
    # channels of one array. Coverage of the true ADEV by the 95 % interval, pooled over the taus
    # with >= 10 independent averages (m <= N/10): 2700 trials, binomial sigma 0.42 % (more with
    # the correlation between taus), so 93-97 % is a >= 3-sigma acceptance band around 95 %.
    n, records = 4096, 300
    rng = np.random.default_rng(42 + int(a))
    h = kasdin_response(n, a)  # Kasdin 1995: h_k = h_{k-1} (k - 1 + a/2) / k
    y = fftconvolve(rng.standard_normal((n, records)), h[:, None], axes=0)[:n]
    curve = deviation(y, 1.0, "oadev", "octave")
    ci = confidence(curve, phase(y, 1.0))
    use = curve.m <= n / 10
    truth = np.sqrt(_true_avar(h, n, curve.m[use]))[:, None]
    covered = (ci.lo[use] <= truth) & (truth <= ci.hi[use])
    assert 0.93 <= covered.mean() <= 0.97, covered.mean(axis=1)
    # with >= 1000 decimated points the lag-1 identification finds the generating exponent
    # (r1 standard error ~0.03, far from the 0.25 rounding threshold in delta)
    assert np.mean(ci.alpha[curve.m <= n / 1000] == alpha_true) > 0.9


def test_noise_id_and_slope_alpha_on_long_records():
    rng = np.random.default_rng(9)
    n = 200_000
    y = np.column_stack([rng.standard_normal(n), np.cumsum(rng.standard_normal(n))])
    curve = deviation(y, 1.0, "oadev", "octave")
    alpha = identify(phase(y, 1.0), curve.m, "oadev")
    mid = (curve.m >= 4) & (curve.m <= n // 100)
    assert np.all(alpha[mid, 0] == 0) and np.all(alpha[mid, 1] == -2)
    slope = alpha_from_slope(curve)
    assert np.all(slope[mid, 0] == 0) and np.all(slope[mid, 1] == -2)


@pytest.mark.parametrize("n", [1, 3, 4, 5, 30, 1000, 65_536])
def test_quadratic_detrend_equals_polyfit_residual(n):
    # white, random-walk and integrated random-walk series on an offset: the projection on the
    # orthogonal basis and numpy's Vandermonde least squares agree to rounding, a few hundred eps of
    # the range (polyfit's own error grows with the offset over the range: 1.4e-13 at n = 4 here)
    rng = np.random.default_rng(n)
    for z in (rng.standard_normal(n), np.cumsum(rng.standard_normal(n)),
              1e3 + np.cumsum(np.cumsum(rng.standard_normal(n)))):
        t = np.arange(n, dtype=float)
        ref = z - np.polyval(np.polyfit(t, z, 2), t) if n >= 3 else np.zeros(n)  # n < 3: any quadratic fits
        assert np.max(np.abs(detrend_quadratic(z) - ref), initial=0.0) <= 1e-12 * max(np.ptp(z), 1.0)


def test_round_alpha_is_numpys_round_and_clip():
    # halves round to even as np.round does (-0.5, 0.5 -> 0; 1.5 -> 2), NaN stays NaN
    values = np.concatenate([np.random.default_rng(3).uniform(-6.0, 4.0, 2000), np.arange(-6.0, 4.5, 0.5)])
    for lo, hi in ((-2, 2), (-4, 2)):
        assert [round_alpha(float(v), lo, hi) for v in values] == [float(np.clip(np.round(v), lo, hi)) for v in values]
    assert np.isnan(round_alpha(float("nan"), -2, 2))


def _flicker_edf_decimal(d: int, m: int, n: int) -> float:
    """Greenhall's rescaled sum for flicker PM (alpha = 1, F = S = m) in 40-digit decimal arithmetic."""
    from decimal import Decimal, getcontext
    from math import comb, floor

    getcontext().prec = 40
    big_m = 1.0 + floor(m * (n - 1 - m * d) / m)
    s, j = float(m), min(big_m, (d + 1) * m)
    if j > 2000:
        scale = 2000 / j
        big_m, s, j = big_m * scale, s * scale, 2000
    f, h, big_s, mm = Decimal(m), 1 / Decimal(m), Decimal(s), Decimal(big_m)

    def g(u):
        return u * u * abs(u).ln() if u != 0 else Decimal(0)

    def sz(t):
        return sum((1 if k % 2 == 0 else -1) * comb(2 * d, d + k) * f * f * (2 * g(t + k) - g(t + k - h) - g(t + k + h))
                   for k in range(-d, d + 1))

    z0 = sz(Decimal(0))
    basic = z0 ** 2 + (1 - Decimal(int(j)) / mm) * sz(Decimal(int(j)) / big_s) ** 2
    basic += sum(2 * (1 - Decimal(i) / mm) * sz(Decimal(i) / big_s) ** 2 for i in range(1, int(j)))
    return float(z0 ** 2 * mm / basic)


def test_flicker_pm_edf_free_of_cancellation():
    # the direct F^2 (2 g(t) - g(t - h) - g(t + h)) loses ~F^2 eps: 2e-11 at m = 2500, 1e-8 at m = 18000;
    # the series / near-zero forms keep double precision. m = 2500 and 2400 share one rescaled lattice
    # (the quadratic-form path), m = 2499 alone on the record-limited one (per-point path); 1e-13 is
    # ~500 eps, an order below the direct sum's error at these F
    ms = np.array([2400, 2500])
    got = edf_greenhall_many(1, 2, ms, 10_001)
    for m, v in zip(ms, got):
        assert v == pytest.approx(_flicker_edf_decimal(2, int(m), 10_001), rel=1e-13)
    assert edf_greenhall(1, 2, 2499, 10_001) == pytest.approx(_flicker_edf_decimal(2, 2499, 10_001), rel=1e-13)
