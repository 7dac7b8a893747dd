"""Spikes in raw magnetometer samples: found against a running median, left out of the point means.

A fit point is the mean of many samples (a static step, or 1° of a table revolution), so a
spike of 20-40 µT in 5 % of the samples moves every point by about a microtesla and no
point-level robust fit can undo it. Each sample is compared with the running median of its
step (:data:`WINDOW` samples: the median of a smooth or linearly changing field is the field,
one or two spikes in the window do not move it); a sample is a spike when one axis departs by
more than :data:`REJECT_SIGMA` (10) times that axis's noise, the noise taken as the robust (MAD)
deviation from the running median over the whole session. Noise passes (the residual of a quantised
signal against its running median reached 6 sigma in 1e-4 of the samples of a simulated
session, 10 in none).

Public: :func:`running_median_residual`, :func:`spike_mask`, :data:`WINDOW`, :data:`REJECT_SIGMA`.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import median_filter

WINDOW = 9  # samples of the running median
REJECT_SIGMA = 10.0  # noise standard deviations beyond which a sample is a spike


def running_median_residual(mag: np.ndarray) -> np.ndarray:
    """Samples (N, 3) µT minus their running median over :data:`WINDOW` samples, µT (edges mirrored, so
    that a spike in the first sample is not copied into its own window)."""
    med = median_filter(np.asarray(mag, float), size=(min(WINDOW, len(mag)), 1), mode="mirror")
    return mag - med


def spike_mask(residuals: list[np.ndarray]) -> list[np.ndarray]:
    """Per step, the mask of spike samples, from the running-median residuals (N_i, 3) µT of every step.

    The noise of each axis is pooled over the steps (1.4826 MAD of the residuals); an axis whose
    noise is below the resolution of the residuals (MAD 0) uses the smallest non-zero deviation.
    """
    pooled = np.concatenate(residuals) if residuals else np.zeros((0, 3))
    if not len(pooled):
        return [np.zeros(0, bool) for _ in residuals]
    dev = np.abs(pooled)
    sigma = 1.4826 * np.median(dev, axis=0)
    for j in np.flatnonzero(sigma <= 0):
        nz = dev[dev[:, j] > 0, j]
        sigma[j] = nz.min() if nz.size else np.inf
    return [np.any(np.abs(r) > REJECT_SIGMA * sigma, axis=1) for r in residuals]
