"""The IEEE Std 952 Allan-variance model, written once (the fit, the theory and the simulator use it).

:data:`FLICKER_AVAR` (the Allan variance of bias instability per B²: 2 ln2 / pi, ADEV floor
0.664 B), :func:`avar_basis` (the model's columns in tau) and :func:`allan_variance` /
:func:`allan_deviation` of given terms. Units: tau in s; a term's unit follows the signal's
(e.g. rad/s: N rad/s/√Hz, B rad/s, K rad/s²/√Hz, Q rad, R rad/s²).

``sigma²(tau) = 3 Q²/tau² + N²/tau + (2 ln2/pi) B² + K² tau/3 + R² tau²/2``
(IEEE Std 952-1997).

:func:`dead_time_variance` is the same model for two averages that are not adjacent (a table
turn between them): half the variance of their difference, the Allan variance times Barnes'
bias function ``B2(spacing / tau)``.
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


def _phase_variogram(h: np.ndarray, white, bias_instability, rrw, quantization) -> np.ndarray:
    """Generalised variogram ``E[(x(t+h) - x(t))²]`` of the phase (time integral of the signal) at lag ``h`` (s).

    Defined up to an even quadratic in ``h`` (which second differences cancel): white ``N² h``,
    flicker ``-(B²/pi) h² ln h``, rate random walk ``-K² h³/6``, quantization (white phase)
    ``2 Q²`` at ``h > 0``. Each is the one whose Allan variance ``(4 V(tau) - V(2 tau)) / (2 tau²)``
    is the IEEE 952 term.
    """
    h = np.abs(np.asarray(h, float))
    pos = h > 0
    log_h = np.log(np.where(pos, h, 1.0))
    return (np.asarray(white, float) ** 2 * h - np.asarray(bias_instability, float) ** 2 / np.pi * h ** 2 * log_h
            - np.asarray(rrw, float) ** 2 * h ** 3 / 6.0 + np.where(pos, 2.0 * np.asarray(quantization, float) ** 2, 0.0))


def dead_time_variance(tau, spacing, white=0.0, bias_instability=0.0, rrw=0.0, quantization=0.0,
                       ramp=0.0) -> np.ndarray:
    """Half the variance of the difference of two ``tau``-s averages whose starts are ``spacing`` s apart.

    ``(2 V(tau) + 2 V(T) - V(T + tau) - V(T - tau)) / (2 tau²)`` with ``V`` the phase variogram
    (:func:`_phase_variogram`) and ``T = spacing >= tau``, plus ``R² T²/2`` for a rate ramp. At
    ``spacing = tau`` it is :func:`allan_variance`; a dead time leaves white noise unchanged and
    raises flicker and random walk (Barnes' B2: ``(3r - 1)/2`` for random walk at ``r = T/tau``).
    Units as :func:`allan_variance`; terms broadcast against ``tau``.
    """
    tau, spacing = np.asarray(tau, float), np.asarray(spacing, float)
    if np.any(spacing < tau * (1.0 - 1e-12)):
        raise ValueError("dead_time_variance: the averages overlap (spacing < tau)")
    gap = np.maximum(spacing - tau, 0.0)

    def v(h):
        return _phase_variogram(h, white, bias_instability, rrw, quantization)

    second = 2.0 * v(tau) + 2.0 * v(spacing) - v(spacing + tau) - v(gap)
    return second / (2.0 * tau ** 2) + np.asarray(ramp, float) ** 2 * spacing ** 2 / 2.0


def window_mean_covariance(start, end, white=0.0, bias_instability=0.0, rrw=0.0, quantization=0.0) -> np.ndarray:
    """Generalised covariance (n, n) of the signal's means over the windows ``[start_i, end_i]`` (s).

    ``Cov(m_a, m_b) = -(V(e_a - e_b) - V(e_a - s_b) - V(s_a - e_b) + V(s_a - s_b)) / (2 T_a T_b)``
    with ``V`` the phase variogram (:func:`_phase_variogram`) of one channel's terms (scalars). Exact
    for every contrast ``w`` of the means (``sum w = 0``, e.g. a mean minus the mean of all, a
    difference of two): ``w C w`` is its variance; a single entry alone means nothing (random walk
    and flicker have no finite variance). Units: the signal's squared.
    """
    s, e = np.asarray(start, float), np.asarray(end, float)

    def v(h):
        return _phase_variogram(h, white, bias_instability, rrw, quantization)

    second = v(e[:, None] - e[None, :]) - v(e[:, None] - s[None, :]) - v(s[:, None] - e[None, :]) \
        + v(s[:, None] - s[None, :])
    span = e - s
    return -0.5 * second / (span[:, None] * span[None, :])
