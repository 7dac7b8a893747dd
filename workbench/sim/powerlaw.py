"""Power-law phase noise for Monte Carlo checks of the stability statistics (Kasdin 1995).

Phase x whose frequency (rate) noise has the spectrum S_y(f) ~ f^alpha, alpha in {2, 1, 0, -1,
-2} (white PM, flicker PM, white FM, flicker FM, random-walk FM): white Gaussian noise through
the 1/f^a filter, a = 2 - alpha, with impulse response h_0 = 1, h_k = h_{k-1} (k - 1 + a/2) / k
(Kasdin, "Discrete simulation of colored noise and stochastic processes", Proc. IEEE 83, 1995),
convolved by FFT. Unit white drive; the phase unit is the caller's (scale as needed).

Public: :data:`NOISE_NAMES`, :func:`kasdin_response`, :func:`power_law_phase`.
"""

from __future__ import annotations

import numpy as np

NOISE_NAMES = {2: "white PM", 1: "flicker PM", 0: "white FM", -1: "flicker FM", -2: "random-walk FM"}


def kasdin_response(n: int, a: float) -> np.ndarray:
    """Impulse response (n,) of the 1/f^a filter."""
    k = np.arange(1, n)
    return np.concatenate(([1.0], np.cumprod((k - 1 + a / 2) / k)))


def power_law_phase(alpha: int, n: int, records: int, rng: np.random.Generator) -> np.ndarray:
    """``records`` independent phase records (records, n) of noise type ``alpha`` (S_y ~ f^alpha)."""
    from scipy.signal import fftconvolve

    h = kasdin_response(n, 2.0 - alpha)
    return fftconvolve(rng.standard_normal((records, n)), h[None, :], axes=1)[:, :n]
