"""Noise generators of the virtual sensor against the IEEE 952 Allan-variance closed forms.

Reference: allantools (overlapping ADEV) and IEEE Std 952-1997 annex C:
white AVAR = N²/τ, flicker AVAR = (2 ln2/π) B², rate random walk AVAR = K² τ/3,
quantization AVAR = 3 Q²/τ². Many independent channels are averaged (in AVAR) so the
statistical spread of the estimate is a few % and the 10 % acceptance is ≥ 4 sigma.
"""

import allantools
import numpy as np

from workbench.sim.noise import (FLICKER_AVAR, IntegratedQuantizer, NoiseProcess, cascade_avar, flicker_design,
                                 flicker_tau_range, round_to_resolution)


def _mean_avar(y: np.ndarray, rate: float, taus: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Overlapping AVAR averaged over the channels of y (n, C), and the relative 1-sigma of
    that mean from the channel-to-channel scatter."""
    avars = []
    for ch in range(y.shape[1]):
        t, ad, _, _ = allantools.oadev(y[:, ch], rate=rate, data_type="freq", taus=taus)
        avars.append(ad**2)
    avars = np.array(avars)
    return t, avars.mean(0), avars.std(0, ddof=1) / np.sqrt(len(avars)) / avars.mean(0)


def test_flicker_design_flat_from_one_sample():
    # Closed-form AVAR of the discrete cascade (PSD integral with the sampled averaging kernel) at
    # integer multiples of dt from one sample to tau_max: within the design's +0.3/-0.6 % of 0.664 B.
    for dt in (0.01, 0.002, 1.0):
        sos, gain = flicker_design(dt)
        lo, hi = flicker_tau_range(dt)
        m = np.unique(np.round(np.r_[np.arange(1, 11), np.logspace(0, np.log10(hi / dt), 40)]))
        ratio = np.sqrt(gain**2 * cascade_avar(sos, dt, m * dt) / FLICKER_AVAR)
        assert lo == dt and hi / lo >= 1e5
        assert np.all((ratio - 1 < 0.003) & (ratio - 1 > -0.006)), (dt, ratio)


def test_cascade_avar_matches_white_closed_form():
    # An empty cascade (all-pass unit section) is white noise: AVAR = dt / τ for unit variance.
    sos = np.array([[1.0, 0, 0, 1.0, -1e-12, 0]])
    taus = np.array([0.1, 1.0, 10.0])
    assert np.allclose(cascade_avar(sos, 0.01, taus), 0.01 / taus, rtol=0.01)


def test_bias_instability_adev_flat_at_0664_b():
    # 64 channels x 2000 s at 10 Hz, tau = 1 sample to 100 s: the mean AVAR over the channels has a
    # relative 1-sigma ``rel`` from the channel scatter (~0.1 % at one sample, ~4 % at 100 s), so the
    # ADEV's is rel / 2; bound: 4 of those plus the design's 0.6 % (the old band-limited cascade was
    # 33 % low at one sample, 11 % at 5).
    dt, b = 0.1, 2.0e-5
    proc = NoiseProcess(np.zeros(64), np.full(64, b), np.zeros(64), dt, seed=11)
    y = proc.generate(20000)
    taus = np.array([0.1, 0.2, 0.5, 1.0, 10.0, 100.0])
    _, avar, rel = _mean_avar(y, 1 / dt, taus)
    ratio = np.sqrt(avar) / (0.664 * b)
    assert np.all(rel < 0.05)  # AVAR; ADEV half of it
    assert np.all(np.abs(ratio - 1) < 4 * rel / 2 + 0.006), (ratio, rel)


def test_white_and_rate_random_walk_adev():
    # white: N/√τ at short τ; RRW: K √(τ/3) at long τ (white/RRW AVAR crossover at τ = √3 N/K = 17 s)
    dt, n_ch = 1.0, 100
    white, rrw = 1e-3, 1e-4
    proc = NoiseProcess(np.full(n_ch, white), np.zeros(n_ch), np.full(n_ch, rrw), dt, seed=5)
    y = proc.generate(10000)
    taus = np.array([1.0, 1000.0])
    t, avar, rel = _mean_avar(y, 1 / dt, taus)
    pred = white**2 / t + rrw**2 * t / 3
    assert white**2 / t[0] > 0.99 * pred[0] and rrw**2 * t[1] / 3 > 0.98 * pred[1]  # each term dominates
    assert np.all(rel < 0.05)  # AVAR; ADEV half of it
    assert np.all(np.abs(np.sqrt(avar / pred) - 1) < 0.10), np.sqrt(avar / pred)


def test_integrated_quantization_adev_and_no_accumulation():
    # The quantization error rate (output - input) must have ADEV √3 Q / τ, and the integral
    # of the output must stay within one step of the integral of the input (no drift).
    dt, q_coef, n_ch = 0.01, 1e-4, 32
    step = np.sqrt(12) * q_coef
    rng = np.random.default_rng(3)
    y = 0.3 + rng.standard_normal((20000, n_ch)) * (3 * step / dt)  # per-sample increment >> step: uniform error
    quant = IntegratedQuantizer(np.full(n_ch, q_coef), dt)
    out = np.vstack([quant.apply(y[:7000]), quant.apply(y[7000:])])
    drift = np.abs(np.cumsum(out - y, axis=0) * dt)
    assert drift.max() <= step * (1 + 1e-9)
    taus = np.array([0.01, 0.1, 1.0])
    t, avar, rel = _mean_avar(out - y, 1 / dt, taus)
    assert np.all(np.abs(np.sqrt(avar) / (np.sqrt(3) * q_coef / t) - 1) < 0.10)


def test_chunked_generation_identical():
    proc_a = NoiseProcess(np.ones(3), np.ones(3), np.ones(3), 0.01, seed=9)
    proc_b = NoiseProcess(np.ones(3), np.ones(3), np.ones(3), 0.01, seed=9)
    whole = proc_a.generate(3000)
    parts = np.vstack([proc_b.generate(k) for k in (1, 999, 1500, 500)])
    assert np.array_equal(whole, parts)


def test_round_to_resolution():
    y = np.array([[0.26, 1.04], [-0.26, 2.0]])
    out = round_to_resolution(y, np.array([0.5, 0.0]))
    assert np.array_equal(out, np.array([[0.5, 1.04], [-0.5, 2.0]]))
