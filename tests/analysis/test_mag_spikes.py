"""Spike rejection of raw magnetometer samples (workbench/analysis/mag_spikes.py) on simulated steps
with known spikes.

Truth: per step a field slowly changing (a rotating board: a linear drift of 2 µT over the step),
white noise sigma = 0.1 µT per axis, and spikes of 20-40 µT on one axis in 5 % of the samples.
- Every spike is found: a spike departs from the running median (9 samples, at most a few spikes in
  a window, so the median is a clean sample) by >= 20 µT - 5 sigma of noise = 19.5 µT, while the
  threshold is 10 x the pooled MAD noise; that noise is that of sample minus running median of
  white noise, ~1.1 sigma, inflated by the 5 % spikes to < 1.3 sigma: threshold < 1.3 µT.
- No clean sample is flagged: a clean residual beyond 10 x (>= 1.0 sigma) is a > 10 sigma Gaussian
  excursion (probability ~1e-23 per sample; 18 000 samples here).
"""

import numpy as np

from workbench.analysis.mag_spikes import WINDOW, running_median_residual, spike_mask

SIGMA = 0.1  # µT


def _steps(seed: int, n_steps: int = 6, n: int = 1000):
    rng = np.random.default_rng(seed)
    steps, truth = [], []
    for _ in range(n_steps):
        field = rng.uniform(-50, 50, 3) + np.outer(np.linspace(0, 1, n), rng.normal(0, 2.0 / np.sqrt(3), 3))
        mag = field + rng.normal(0.0, SIGMA, (n, 3))
        spikes = rng.random(n) < 0.05
        axis = rng.integers(0, 3, n)
        size = rng.uniform(20, 40, n) * rng.choice([-1, 1], n)
        mag[spikes, axis[spikes]] += size[spikes]
        steps.append(mag)
        truth.append(spikes)
    return steps, truth


def test_every_spike_found_and_no_clean_sample_flagged():
    steps, truth = _steps(21)
    masks = spike_mask([running_median_residual(s) for s in steps])
    for mask, spikes in zip(masks, truth):
        assert mask.shape == spikes.shape
        np.testing.assert_array_equal(mask, spikes)


def test_running_median_of_a_clean_linear_field_is_the_field():
    """Noise-free linear field: the median of a window of a monotone sequence is its middle sample, the
    field itself, so the residual is 0 (float rounding, 1e-12 µT) wherever the window lies inside the
    step (the mirrored edges fold the line, and there the residual is up to slope x WINDOW / 2)."""
    t = np.arange(200.0)
    mag = np.column_stack([10 + 0.01 * t, -5 - 0.02 * t, 30 + 0 * t])
    res = running_median_residual(mag)
    h = WINDOW // 2
    np.testing.assert_allclose(res[h:-h], 0.0, atol=1e-12)
    assert np.all(np.abs(res) <= 0.02 * WINDOW / 2 + 1e-12)


def test_spike_in_the_first_sample_is_found():
    """Edge mirroring: the first sample's window holds it once, so the median is a clean neighbour."""
    rng = np.random.default_rng(3)
    mag = 20.0 + rng.normal(0.0, SIGMA, (300, 3))
    mag[0, 1] += 30.0
    mask = spike_mask([running_median_residual(mag)])[0]
    assert mask[0]
    assert mask.sum() == 1


def test_quantised_axis_with_zero_mad_uses_the_smallest_step():
    """A constant quantised axis (resolution 0.15 µT, MAD 0): its noise falls back to the smallest
    non-zero deviation (one LSB), so a one-LSB flicker passes (< 10 LSB) and a 30 µT spike is found."""
    n = 500
    rng = np.random.default_rng(4)
    mag = np.column_stack([rng.normal(5, SIGMA, n), rng.normal(-7, SIGMA, n), np.full(n, 42.0)])
    mag[rng.choice(n, 5, replace=False), 2] += 0.15  # isolated single-LSB flicker
    mag[250, 2] += 30.0
    mask = spike_mask([running_median_residual(mag)])[0]
    assert mask[250]
    assert mask.sum() == 1
