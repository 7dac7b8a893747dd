"""The IEEE Std 952 Allan-variance model, written once (the fit, the theory and the simulator use it).

:data:`FLICKER_AVAR` (the Allan variance of bias instability per B²: 2 ln2 / pi, ADEV floor
0.664 B), :func:`avar_basis` (the model's columns in tau) and :func:`allan_variance` /
:func:`allan_deviation` of given terms. Units: tau in s; a term's unit follows the signal's
(e.g. rad/s: N rad/s/√Hz, B rad/s, K rad/s²/√Hz, Q rad, R rad/s²).

``sigma²(tau) = 3 Q²/tau² + N²/tau + (2 ln2/pi) B² + K² tau/3 + R² tau²/2``
(IEEE Std 952-1997).
"""

from __future__ import annotations

import numpy as np

FLICKER_AVAR = 2.0 * np.log(2.0) / np.pi  # AVAR of bias instability per B², IEEE 952 (ADEV floor 0.664 B)


def avar_basis(tau) -> np.ndarray:
    """Columns (..., 5) of the model in ``tau`` (s): weights of Q², N², B², K², R² in that order."""
    tau = np.asarray(tau, float)
    return np.stack([3.0 / tau ** 2, 1.0 / tau, np.full_like(tau, FLICKER_AVAR), tau / 3.0, tau ** 2 / 2.0], axis=-1)


def allan_variance(tau, white=0.0, bias_instability=0.0, rrw=0.0, quantization=0.0, ramp=0.0) -> np.ndarray:
    """Allan variance of the terms at ``tau`` (s); the terms broadcast against ``tau`` (e.g. (3,) per axis)."""
    b = avar_basis(tau)
    return (b[..., 0] * np.asarray(quantization, float) ** 2 + b[..., 1] * np.asarray(white, float) ** 2
            + b[..., 2] * np.asarray(bias_instability, float) ** 2 + b[..., 3] * np.asarray(rrw, float) ** 2
            + b[..., 4] * np.asarray(ramp, float) ** 2)


def allan_deviation(tau, white=0.0, bias_instability=0.0, rrw=0.0, quantization=0.0, ramp=0.0) -> np.ndarray:
    """Allan deviation (the square root of :func:`allan_variance`)."""
    return np.sqrt(allan_variance(tau, white, bias_instability, rrw, quantization, ramp))
