"""The bias instability of a noise block as a first-order Gauss-Markov state of the navigation filters.

Bias instability ``B`` is flicker noise (PSD ``B² / (2π f)``, Allan deviation flat at 0.664 B): no
finite-state model has it exactly. A filter that treats the bias as a random constant plus a random
walk lets it move far less between two stops than flicker does (the land INS heading 2x optimistic
after the pre-calibration, docs/navigation.md). The standard finite-state stand-in is a first-order
Gauss-Markov (exponentially correlated) process of steady-state sigma ``σ`` and correlation time
``T``, ``ḃ = -b / T + w``, ``E[w²] = 2 σ² / T``, whose Allan variance (IEEE Std 952-1997 annex C,
"exponentially correlated (Markov) noise"; El-Sheimy, Hou, Niu, IEEE Trans. Instrum. Meas. 57(1),
2008, sec. on exponentially correlated noise) is

    AVAR(τ) = (2 σ² / x) [1 - (3 - 4 e^(-x) + e^(-2x)) / (2 x)],   x = τ / T,

a rate random walk ``2 σ² τ / (3 T)`` for ``τ << T``, white ``2 σ² T / τ`` for ``τ >> T``, with one
peak: ADEV ``GM_PEAK_ADEV σ`` (0.6174) at ``τ = GM_PEAK_X T`` (1.893), both computed here from the
formula. The mapping used (:func:`gauss_markov_from_allan`): the process's peak is put on the flicker
floor where the noise block's own model ADEV has its minimum, the time scale at which the bias
instability dominates the record,

    T = τ_min / GM_PEAK_X,   σ = 0.664 B / GM_PEAK_ADEV (= 1.076 B),

with ``τ_min`` the minimum of the IEEE 952 model of the block (white, B, rate random walk,
quantization, rate ramp; :mod:`workbench.allan_model`), capped at ``tau_cap_s`` when nothing rises
after the floor (no rate random walk or ramp observed). The rate random walk stays a random walk of
its own; the Gauss-Markov replaces the ``B² / τ`` share of the bias random walk.

One state is not flicker: matched at ``τ_min`` its ADEV falls as ``√τ`` below and as ``1/√τ`` above,
so between two stops (100-300 s) it lets the bias move by less than half of what flicker does (the
land INS heading 1.7x optimistic). :func:`flicker_ladder` is the standard remedy: a sum of ``L``
first-order Gauss-Markov processes whose correlation times are one decade apart and centred on
``τ_min / GM_PEAK_X``,

    T_k = (τ_min / GM_PEAK_X) 10^(k - (L - 1) / 2),   k = 0 .. L-1,

with variances ``w_k B²`` fitted (non-negative least squares on the log of τ) so that the sum's Allan
variance is the flicker's ``(2 ln 2 / π) B²`` over the span of the rungs' peaks, ``τ_min 10^(±(L-1)/2)``.
The spectral reason it works: the two-sided PSD ``Σ 2 σ_k² T_k / (1 + (2π f T_k)²)`` with
``σ_k² = B² ln 10 / π`` per decade (0.86 B per rung) tends to the flicker's ``B² / (2π f)`` as the rungs
get dense; the fit (0.95, 0.82, 0.96 B for three) corrects the end rungs for the missing neighbours. With three rungs the ladder's ADEV is within 1.5 % of
0.664 B over two decades (tests/nav/test_bias_model.py). The weights depend on ``L`` only (the
fit is scale-free in τ), so they are computed once.

Public: :data:`GM_PEAK_X`, :data:`GM_PEAK_ADEV`, :data:`LADDER_RUNGS`, :func:`gauss_markov_avar`,
:func:`allan_minimum_tau`, :func:`gauss_markov_from_allan`, :func:`ladder_weights`, :func:`flicker_ladder`.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.optimize import minimize_scalar, nnls

from workbench.allan_model import FLICKER_AVAR, allan_variance

LADDER_RUNGS = 3  # default number of Gauss-Markov rungs per axis of a flicker ladder (one per decade)
TAU_CAP_S = 1.0e5  # s: where the minimum is sought (and the answer when the block's ADEV does not rise after the floor)


def gauss_markov_avar(tau, sigma, corr_time) -> np.ndarray:
    """Allan variance (u²) at ``tau`` (s) of a first-order Gauss-Markov process of steady-state ``sigma`` (u)
    and correlation time ``corr_time`` (s) (module docstring; the arguments broadcast)."""
    x = np.asarray(tau, float) / np.asarray(corr_time, float)
    small = x < 1e-4  # the series 2x/3 - x²/6 where the closed form cancels
    xs = np.where(small, 1.0, x)
    full = 2.0 / xs * (1.0 - (3.0 - 4.0 * np.exp(-xs) + np.exp(-2.0 * xs)) / (2.0 * xs))
    return np.asarray(sigma, float) ** 2 * np.where(small, 2.0 * x / 3.0 - x ** 2 / 6.0, full)


@lru_cache(maxsize=1)
def _peak() -> tuple[float, float]:
    """(x, ADEV / sigma) at the peak of the unit process's Allan deviation."""
    res = minimize_scalar(lambda lx: -gauss_markov_avar(np.exp(lx), 1.0, 1.0), bounds=(-2.0, 4.0), method="bounded",
                          options={"xatol": 1e-10})
    return float(np.exp(res.x)), float(np.sqrt(-res.fun))


GM_PEAK_X, GM_PEAK_ADEV = _peak()  # 1.893, 0.6174


def allan_minimum_tau(white=0.0, bias_instability=0.0, rrw=0.0, quantization=0.0, ramp=0.0,
                      tau_cap_s: float = TAU_CAP_S) -> np.ndarray:
    """τ (s) of the minimum of the IEEE 952 model ADEV of the terms (per axis, broadcast; NaN counts as 0),
    on a grid of 200 points per decade up to ``tau_cap_s`` (returned where the model does not rise again)."""
    terms = [np.nan_to_num(np.asarray(v, float)) for v in (white, bias_instability, rrw, quantization, ramp)]
    shape = np.broadcast(*terms).shape
    taus = np.logspace(-3.0, np.log10(tau_cap_s), 200 * int(np.ceil(np.log10(tau_cap_s) + 3.0)) + 1)
    avar = allan_variance(taus.reshape((-1,) + (1,) * len(shape)), *terms)
    return taus[np.argmin(avar, axis=0)]


def gauss_markov_from_allan(white, bias_instability, rrw=0.0, quantization=0.0, ramp=0.0,
                            tau_cap_s: float = TAU_CAP_S) -> tuple[np.ndarray, np.ndarray]:
    """(sigma, correlation time s) per axis of the Gauss-Markov stand-in for the bias instability ``B`` of a
    noise block (module docstring): ``σ = 0.664 B / GM_PEAK_ADEV``, ``T = τ_min / GM_PEAK_X``. Terms in the
    signal's SI unit (``white`` u/√Hz, ``B`` u, ``rrw`` u/√s, ``quantization`` u·s, ``ramp`` u/s); a NaN
    (not observed) ``B`` gives sigma 0 (no state)."""
    b = np.nan_to_num(np.asarray(bias_instability, float))
    tau_min = allan_minimum_tau(white, b, rrw, quantization, ramp, tau_cap_s)
    return np.sqrt(FLICKER_AVAR) * b / GM_PEAK_ADEV, tau_min / GM_PEAK_X


@lru_cache(maxsize=8)
def ladder_weights(rungs: int) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(x_k, w_k) of a ladder of ``rungs`` Gauss-Markov processes (module docstring): correlation times
    ``x_k τ_min`` and variances ``w_k B²`` whose summed Allan variance is the flicker's ``FLICKER_AVAR B²``
    (NNLS on 200 log-spaced τ per decade between the outer rungs' peaks). One rung: the single state of
    :func:`gauss_markov_from_allan` (``x = 1 / GM_PEAK_X``, ``w = FLICKER_AVAR / GM_PEAK_ADEV²``)."""
    if rungs < 1:
        raise ValueError(f"flicker ladder: rungs={rungs} is not a whole number >= 1")
    x = 10.0 ** (np.arange(rungs) - (rungs - 1) / 2.0) / GM_PEAK_X
    if rungs == 1:
        return (float(x[0]),), (FLICKER_AVAR / GM_PEAK_ADEV ** 2,)
    span = (rungs - 1) / 2.0
    taus = np.logspace(-span, span, 200 * (rungs - 1) + 1)
    basis = gauss_markov_avar(taus[:, None], 1.0, x[None, :])
    w, _ = nnls(basis / FLICKER_AVAR, np.ones(taus.size))
    return tuple(map(float, x)), tuple(map(float, w))


def flicker_ladder(white, bias_instability, rrw=0.0, quantization=0.0, ramp=0.0, rungs: int = LADDER_RUNGS,
                   tau_cap_s: float = TAU_CAP_S) -> tuple[np.ndarray, np.ndarray]:
    """(sigma (rungs, 3) u, correlation time (rungs, 3) s) of the Gauss-Markov ladder that stands in for the
    bias instability ``B`` of a noise block (module docstring): rungs a decade apart centred on the block's
    Allan minimum ``τ_min`` (:func:`allan_minimum_tau`), variances from :func:`ladder_weights`. Terms as
    :func:`gauss_markov_from_allan`; a NaN (not observed) ``B`` gives sigmas 0 (no states)."""
    b = np.nan_to_num(np.asarray(bias_instability, float))
    tau_min = allan_minimum_tau(white, b, rrw, quantization, ramp, tau_cap_s)
    x, w = (np.asarray(v)[:, None] for v in ladder_weights(int(rungs)))
    shape = (len(x),) + np.broadcast(b, tau_min).shape
    return np.broadcast_to(np.sqrt(w) * b, shape).copy(), np.broadcast_to(x * tau_min, shape).copy()
