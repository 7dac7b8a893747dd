"""Stateful, vectorised noise generators of the virtual sensor (IEEE 952 terms).

Each generator keeps its state between calls, so a record generated in chunks is
sample-for-sample identical to one generated in a single call with the same seed (the
random numbers are drawn as a row-major ``(n, channels)`` block, which numpy's
``Generator`` fills sequentially, and every filter carries its state).

Terms, per channel, in the channel's SI unit ``u`` (rad/s, m/s^2, µT):

* white noise of density ``N`` (u/√Hz, e.g. rad/s/√Hz = rad/√s): AVAR = N² / τ;
* bias instability ``B`` (u): flicker noise, PSD ``B² / (2π f)``, AVAR flat at
  ``2 ln2 / π · B²`` (ADEV floor 0.664 B), made by a cascade of first-order pole/zero
  sections (two per decade, a fitted roll-off near Nyquist) driven by one white sequence; the
  sampled ADEV is flat within +0.3/-0.6 % from one sample ``dt`` to ``1e5 s`` (:func:`flicker_design`);
* rate random walk ``K`` (u/√s, i.e. u/s/√Hz): AVAR = K² τ / 3;
* quantization ``Q`` (u·s, e.g. rad, m/s): the *integrated* output (angle, velocity) is
  quantized with step ``√12 · Q``, the remainder carried to the next sample, giving
  AVAR = 3 Q² / τ² (IEEE 952 Q is the RMS of the integrated quantization error).

References: IEEE Std 952-1997 annex C (Allan variance of the noise terms); thesis
(shared/seeds/000_...) sec. 1.2 tables 1.1, 1.2 (ARW / VRW and bias instability).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from workbench.allan_model import FLICKER_AVAR
from workbench.sim.filters import sosfilt_rows

FLICKER_TAU_MAX_S = 1.0e5  # s, upper end of the flat ADEV of the bias-instability process
FLICKER_SECTIONS_PER_DECADE = 2
FLICKER_TOP = 0.01  # highest pole of the regular ladder, in units of the sample rate
FLICKER_ROLL_OFF = (0.03164, 0.05915, 0.1297)  # pole, zero, pole above the ladder (units of the sample rate):
# least-squares fit (scipy.optimize.least_squares) of the discrete cascade's AVAR (cascade_avar) at 1..1e4
# samples to a flat level; the sampled ADEV is then within +0.26/-0.56 % of 0.664 B from one sample to tau_max


def flicker_tau_range(dt: float) -> tuple[float, float]:
    """(tau_min, tau_max), s, over which the bias-instability ADEV is flat at sample period ``dt`` s:
    from one sample on."""
    return dt, FLICKER_TAU_MAX_S


def _flicker_corners(dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Pole and zero frequencies (Hz) of the flicker cascade: poles two per decade from
    :data:`FLICKER_TOP` of the sample rate down to a tenth of ``1/(2 pi tau_max)``, each with a zero a
    quarter decade above, then the roll-off :data:`FLICKER_ROLL_OFF` towards Nyquist."""
    top, f_lo = FLICKER_TOP / dt, 1.0 / (2 * np.pi * FLICKER_TAU_MAX_S) / 10.0
    n_poles = int(np.ceil(np.log10(top / f_lo) * FLICKER_SECTIONS_PER_DECADE)) + 1
    poles = top * 10.0 ** (-np.arange(n_poles)[::-1] / FLICKER_SECTIONS_PER_DECADE)
    zeros = poles * 10.0 ** (0.5 / FLICKER_SECTIONS_PER_DECADE)
    p1, z1, p2 = (f / dt for f in FLICKER_ROLL_OFF)
    return np.concatenate([poles, [p1, p2]]), np.concatenate([zeros, [z1]])


def _cascade_sos(dt: float) -> np.ndarray:
    """First-order sections (matched z-transform of the corners), shape (P, 6)."""
    poles, zeros = _flicker_corners(dt)
    sos = np.zeros((poles.size, 6))
    sos[:, 0] = 1.0
    sos[:, 3] = 1.0
    sos[:, 4] = -np.exp(-2 * np.pi * poles * dt)
    sos[: zeros.size, 1] = -np.exp(-2 * np.pi * zeros * dt)
    return sos


def cascade_avar(sos: np.ndarray, dt: float, taus: np.ndarray) -> np.ndarray:
    """Allan variance at ``taus`` (s) of the output of ``sos`` driven by unit-variance
    white noise at period ``dt``: AVAR(τ) = ∫ S(f) |H_A(f)|² df with the discrete
    averaging kernel |H_A|² = 2 sin⁴(π f τ) / (m² sin²(π f dt)), m = τ / dt."""
    taus = np.asarray(taus, float)
    f_pole = -np.log(np.clip(-sos[:, 4], 1e-300, None)).min() / (2 * np.pi * dt)  # lowest corner, Hz
    f_min = 1e-3 * min(f_pole, 1.0 / taus.max())
    f = np.logspace(np.log10(f_min), np.log10(0.5 / dt), 20000)
    e = np.exp(-2j * np.pi * f * dt)
    h2 = np.ones(f.size)
    for b0, b1, _, _, a1, _ in sos:
        h2 *= np.abs(b0 + b1 * e) ** 2 / np.abs(1.0 + a1 * e) ** 2
    psd = 2.0 * dt * h2  # one-sided PSD of the output, per unit input variance
    out = np.empty(len(taus))
    for i, tau in enumerate(taus):
        x = np.pi * f * tau
        sin4 = np.where(x > 30.0, 3.0 / 8.0, np.sin(x) ** 4)  # mean of sin⁴ where it oscillates faster than the grid
        kernel = 2.0 * sin4 / ((tau / dt) ** 2 * np.sin(np.pi * f * dt) ** 2)
        out[i] = np.trapezoid(psd * kernel * f, np.log(f))
    return out


@lru_cache(maxsize=16)
def flicker_design(dt: float) -> tuple[np.ndarray, float]:
    """Second-order-section cascade (P, 6) and the input gain that make unit-B flicker noise.

    Driving the cascade with white noise of standard deviation ``gain · B`` gives a process
    whose sampled ADEV (integer multiples of ``dt``) is 0.664 B (geometric mean over
    :func:`flicker_tau_range`), within +0.3/-0.6 % from one sample to tau_max.
    """
    sos = _cascade_sos(dt)
    tau_min, tau_max = flicker_tau_range(dt)
    m = np.unique(np.round(np.logspace(0.0, np.log10(tau_max / tau_min), 40)))
    level = np.exp(np.mean(0.5 * np.log(cascade_avar(sos, dt, m * dt))))
    sos.setflags(write=False)
    return sos, float(np.sqrt(FLICKER_AVAR) / level)


class NoiseProcess:
    """Additive noise of ``C`` channels: white + bias instability + rate random walk.

    Parameters
    ----------
    white : (C,) density, u/√Hz
    bias_instability : (C,) B, u
    rrw : (C,) K, u/√s
    dt : sample period, s
    seed : seed of the noise; each term draws from its own child stream, one ``(n, C)``
        block per call, so a term that is zero does not change the others' samples

    The bias-instability and rate-random-walk states start at zero: the unit's turn-on
    bias is the deterministic bias, and the slow processes wander from it.
    """

    def __init__(self, white: np.ndarray, bias_instability: np.ndarray, rrw: np.ndarray, dt: float,
                 seed: int | np.random.SeedSequence) -> None:
        self.white_std = np.asarray(white, float) / np.sqrt(dt)  # per-sample std, u
        self.rrw_std = np.asarray(rrw, float) * np.sqrt(dt)  # per-sample rate step, u
        sos, gain = flicker_design(float(dt))
        self.sos = sos.copy()  # the filter kernel takes a writable array
        self.flicker_std = gain * np.asarray(bias_instability, float)
        self.channels = self.white_std.size
        seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        self._rng_white, self._rng_flicker, self._rng_rrw = map(np.random.default_rng, seq.spawn(3))
        self._zi_flicker = np.zeros((self.channels, self.sos.shape[0], 2))  # per channel, per section
        self._rrw_state = np.zeros(self.channels)

    def generate(self, n: int) -> np.ndarray:
        """Next ``n`` samples of the noise, (n, C), u."""
        out = self._rng_white.standard_normal((n, self.channels))
        out *= self.white_std
        if np.any(self.flicker_std):
            flick = np.ascontiguousarray(self._rng_flicker.standard_normal((n, self.channels)).T)
            sosfilt_rows(self.sos, flick, self._zi_flicker)  # in place, one row per channel
            flick *= self.flicker_std[:, None]
            out += flick.T
        if np.any(self.rrw_std):
            walk = self._rng_rrw.standard_normal((n, self.channels))
            walk *= self.rrw_std
            walk[0] += self._rrw_state
            np.cumsum(walk, axis=0, out=walk)  # sequential: chunking-exact
            self._rrw_state = walk[-1].copy()
            out += walk
        return out

    def state(self) -> dict:
        """JSON-ready state (generators and filter memories) for :meth:`restore`; the flicker memories
        section by section, (P, C, 2)."""
        return {"rng": [r.bit_generator.state for r in (self._rng_white, self._rng_flicker, self._rng_rrw)],
                "flicker": self._zi_flicker.transpose(1, 0, 2).tolist(), "rrw": self._rrw_state.tolist()}

    def restore(self, state: dict) -> None:
        """Continue from a :meth:`state` taken earlier (e.g. when a recording is resumed)."""
        for rng, st in zip((self._rng_white, self._rng_flicker, self._rng_rrw), state["rng"]):
            rng.bit_generator.state = st
        sections = np.array(state["flicker"], float).reshape(self.sos.shape[0], self.channels, 2)
        self._zi_flicker = np.ascontiguousarray(sections.transpose(1, 0, 2))
        self._rrw_state = np.array(state["rrw"], float).reshape(self.channels)


class IntegratedQuantizer:
    """Quantizes the integral of a (n, C) signal with step ``√12 · Q`` (IEEE 952 Q, u·s).

    Output sample k is ``(floor(S_k / q) - floor(S_{k-1} / q)) · q / dt`` where ``S`` is the
    running integral, so the quantization error never accumulates (as in a delta-angle /
    delta-velocity output). Channels with Q = 0 pass through unchanged.
    """

    def __init__(self, quantization: np.ndarray, dt: float) -> None:
        self.step = np.sqrt(12.0) * np.asarray(quantization, float)
        self.dt = dt
        self.active = self.step > 0
        self._integral = np.zeros(int(self.active.sum()))
        self._count = np.zeros(int(self.active.sum()))

    def apply(self, y: np.ndarray) -> np.ndarray:
        """Quantized copy of ``y`` (n, C), u."""
        if not np.any(self.active):
            return y
        out = y.copy()
        q = self.step[self.active]
        inc = np.vstack([self._integral, y[:, self.active] * self.dt])
        integral = np.cumsum(inc, axis=0)[1:]
        counts = np.floor(integral / q)
        out[:, self.active] = np.diff(np.vstack([self._count, counts]), axis=0) * (q / self.dt)
        self._integral, self._count = integral[-1], counts[-1]
        return out

    def state(self) -> dict:
        """JSON-ready state (running integral and count) for :meth:`restore`."""
        return {"integral": self._integral.tolist(), "count": self._count.tolist()}

    def restore(self, state: dict) -> None:
        """Continue from a :meth:`state` taken earlier."""
        self._integral = np.array(state["integral"], float).reshape(self._integral.shape)
        self._count = np.array(state["count"], float).reshape(self._count.shape)


def round_to_resolution(y: np.ndarray, resolution: np.ndarray) -> np.ndarray:
    """Round each channel of ``y`` (n, C) to its output LSB ``resolution`` (C,), u; 0 = none.

    For noise well above one LSB this adds white noise of variance LSB² / 12 per sample.
    """
    res = np.asarray(resolution, float)
    active = res > 0
    if not active.any():
        return y
    out = y.copy()
    out[:, active] = np.round(y[:, active] / res[active]) * res[active]
    return out
