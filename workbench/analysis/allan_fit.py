"""IEEE Std 952 noise-term fit of an Allan variance curve, with model selection.

Model of the Allan variance of rate data (IEEE Std 952-1997 Annex C, table C.2):

    AVAR(tau) = 3 Q^2 / tau^2 + N^2 / tau + (2 ln2 / pi) B^2 + K^2 tau / 3 + R^2 tau^2 / 2

Q quantization (rad | m/s), N white noise density (ARW rad/s/sqrt(Hz) | VRW m/s^2/sqrt(Hz)),
B bias instability (rad/s | m/s^2), K rate random walk (rad/s^2/sqrt(Hz) | m/s^3/sqrt(Hz)),
R rate ramp (rad/s^2 | m/s^3).

Quantization beside white noise. ``3 Q^2 / tau^2`` holds when the quantization error of the
integrated output is white, i.e. when the integral moves by many steps ``q = sqrt(12) Q``
between samples. A unit with a coarse step and little white noise (a dithered RLG's angle
quantization, an accelerometer's delta-velocity LSB) is the other case: the error is
``e = S mod q`` of the integral ``S``, which a random walk of density N moves slowly, and
neighbouring errors are correlated. With ``e`` uniform and independent of the increments,
``cov(e_k, e_k+m) = q^2 / (2 pi^2) sum_n n^-2 exp(-2 pi^2 n^2 N^2 tau / q^2)`` and the cross
term with the white noise vanishes, so the quantization term becomes ``3 Q^2 h(tau) / tau^2``
with ``h = 1 - 4/3 rho(x) + 1/3 rho(2x)``, ``rho`` the correlation above and
``x = N^2 tau / (12 Q^2)`` (:func:`quantization_shape`; h -> 1 for x >> 1, the IEEE form, and
~ sqrt(tau) for x << 1, where the classic model overstates the variance by up to 2x at the
first tau). White noise is not all that moves the integral: the record's slow rate (bias
instability, rate random walk, its mean) adds M(tau) tau^2 to the increment's variance N^2 tau
(:class:`SlowRate`, M from the record's 10-s mean square and the fitted N, Q, B); without it the
shape is exact for white noise alone but 0.4-2 % low at m = 1-8 on a 2-h hg1700 accel record,
which biased Q by +1.5 %. With it the shape matches the virtual quantizer within 0.2 % at m = 1-64
(tests/analysis/test_allan_fit.py). A mean moving the integral by a sizeable fraction of a step
per sample (gravity on a delta-velocity channel) makes the error a deterministic pattern of that
fraction instead, which this Gaussian form does not describe. The shape ties Q and N: the ratio r = N^2 / Q^2 is a
parameter of the model (N^2 = r Q^2 enforced), found by a 1-D search of the deviance over r, with
the edges of no white noise and of h = 1 (the IEEE form, Q = 0 included) in the family
(:class:`_Family`); the same search runs at every profile point and in every model of the selection.

The model is linear in the squared coefficients theta for a given r. Each AVAR
point is a scaled chi-squared variable with the Greenhall EDF, so the fit maximises the gamma
likelihood (non-negative IRLS with weights edf / model^2, the identity-link gamma GLM); its
deviance is divided by :data:`CORRELATION` (neighbouring overlapping points share about half
their information).

Values and intervals come from the full five-term fit: a term's 95 % interval is the set of
values whose profile deviance (the other four terms and r refitted, all non-negative) lies within
chi2(0.95, 1) = 3.84 of the minimum. It does not depend on which terms are reported, so
choosing the model does not make the intervals optimistic (a rate random walk selected because
the last octaves fluctuated up keeps an interval reaching down to the truth: the selection of
the old subset/BIC fit reported 2-2.5x RRW with intervals excluding it, issue 19 item 5).
Reported ("observed") are the terms that survive backward elimination from the full model by
likelihood ratio (a term is dropped while removing it raises the deviance by less than 3.84);
a term not observed is NaN with the interval [0, profile upper limit]. An observed term whose
profile reaches 0 gets a lower limit of 0: the data do not exclude its absence.

Classic read-offs for comparison with datasheets and the thesis tables (1.1, 1.2, 2.1, 4.1):
N on the slope -1/2 line at tau = 1 s, K on the slope +1/2 line at tau = 3 s, B = min ADEV / 0.664.

Public: :data:`TERMS`, :class:`NoiseTerm`, :class:`ChannelNoise`, :func:`fit_channel`, :func:`fit_terms`,
:func:`read_offs`, :class:`AllanAnalysis` (with its ``to_dict`` / ``summary``, in
:mod:`workbench.analysis.allan_report`, re-exported), :func:`analyze_record`, :func:`analyze_stream`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from workbench.allan_model import FLICKER_AVAR, avar_basis
from workbench.analysis.allan_ci import MAX_POINTS_ID, DeviationCI, chi2_ppf
from workbench.analysis.allan_report import CALSET_NAMES, AllanAnalysis  # noqa: F401 (re-exported)
from workbench.analysis.allan_terms import TERMS
from workbench.analysis.small_solvers import minimize_bounded, root_bracket

FLICKER = FLICKER_AVAR  # AVAR per B^2; ADEV floor 0.664 B (workbench.allan_model)
CORRELATION = 2.0  # overlapping AVAR points at octave taus share about half their information:
# weighted chi-squared differences are divided by this before model comparison
SLOW_WINDOW_S = 10.0  # s, longest averaging time of the rate mean square behind the slow rate (SlowRate)
SLOW_MIN_WINDOWS = 20  # windows of it the record must hold
_IRLS_ITER = 30
_IRLS_STEP = 1e-4  # change of the model AVAR, in each point's standard deviation, at which the IRLS stops


def basis(tau: np.ndarray, ratio: float = np.inf, slow: SlowRate | None = None, q2: float = 0.0) -> np.ndarray:
    """AVAR basis (K, 5) at taus (s): 3 h/tau^2, 1/tau, 2 ln2/pi, tau/3, tau^2/2
    (:func:`workbench.allan_model.avar_basis`), with the quantization shape h of :func:`quantization_shape`
    for ``ratio`` = N^2 / Q^2 (1/s; inf: h = 1), the record's slow rate ``slow`` and ``q2`` = Q^2 (u^2 s^2)."""
    a = avar_basis(np.atleast_1d(np.asarray(tau, float)))
    if np.isfinite(ratio):
        a[:, 0] *= quantization_shape(a[:, 1] ** -1, ratio, slow, q2)
    return a


@dataclass(frozen=True)
class SlowRate:
    """What moves a record's integral between samples besides white noise: the mean square M(tau) (u^2) of
    the rate without its white noise, averaged over tau, mean included, over the whole record.

    ``M(tau) = at_1s - flicker ln(tau / 1 s)``: flicker noise of one-sided PSD h_-1 / f (h_-1 = B^2 / pi) adds
    h_-1 ln(W / tau) between averaging times W and tau (the Frullani integral of its PSD against sinc^2),
    rate random walk and the record's mean are constant over the short taus where the shape matters.
    """

    at_1s: float
    flicker: float

    def mean_square(self, tau: np.ndarray) -> np.ndarray:
        """M(tau) (u^2) at taus (s), never below 0."""
        return np.maximum(self.at_1s - self.flicker * np.log(np.asarray(tau, float)), 0.0)

    @classmethod
    def from_record(cls, window: float, mean_square: float, n2: float, q2: float, b2: float) -> SlowRate:
        """From the record's mean square ``mean_square`` (u^2) of its rate averaged over ``window`` (s) and the
        fitted N^2 (u^2/Hz), Q^2 (u^2 s^2), B^2 (u^2): the white part N^2 / W and the quantization part
        2 Q^2 (1 - rho(W)) / W^2 of the averaged rate removed, the flicker part extrapolated with h_-1 = B^2 / pi."""
        rho = float(_sawtooth_correlation(np.array(n2 * window / (12.0 * q2)))) if q2 > 0 else 0.0
        at_w = max(mean_square - n2 / window - 2.0 * q2 * (1.0 - rho) / window ** 2, 0.0)
        h = b2 * FLICKER / (2.0 * np.log(2.0))
        return cls(at_w + h * np.log(window), h)


def _sawtooth_correlation(x: np.ndarray) -> np.ndarray:
    """Correlation of ``S mod q`` at two instants whose integral increment has variance ``x q^2``:
    (6 / pi^2) sum_n n^-2 exp(-2 pi^2 n^2 x); the small-x form pi^2/6 - sqrt(pi a) + a/2 of the sum
    (a = 2 pi^2 x) is exact to ~1e-9 below a = 0.5, the series is cut at n = 24 above it."""
    a = 2.0 * np.pi ** 2 * np.maximum(np.asarray(x, float), 0.0)
    small = a < 0.5
    total = np.empty_like(a)
    total[small] = np.pi ** 2 / 6.0 - np.sqrt(np.pi * a[small]) + a[small] / 2.0
    big = a[~small]
    total[~small] = np.sum(np.exp(-_N_SQUARED * big[None, :]) / _N_SQUARED, axis=0)
    return 6.0 / np.pi ** 2 * total


_N_SQUARED = np.arange(1, 25, dtype=float)[:, None] ** 2  # the terms n^2 of the sawtooth series


def quantization_shape(tau: np.ndarray, ratio: float, slow: SlowRate | None = None, q2: float = 0.0) -> np.ndarray:
    """h(tau) in [0, 1] of the quantization term ``3 Q^2 h / tau^2`` beside white noise N (module docstring).

    ``ratio`` = N^2 / Q^2 (1/s; N u/sqrt(Hz), Q u*s); inf gives the IEEE 952 form h = 1 and 0
    (no white noise) the same, since then nothing moves the integral between steps but the slow terms.
    ``slow`` (with ``q2`` = Q^2, u^2 s^2): the record's slow rate, whose integral over tau adds a variance
    M(tau) tau^2 to the white noise's N^2 tau (Gaussian to second order in the rate's mean: valid while the
    mean moves the integral by well under a step within the correlation time 12 Q^2 / N^2).
    ``ratio`` and ``q2`` may be arrays broadcasting against ``tau`` (the ratios then finite and > 0): one
    shape per element, e.g. (G, 1) for G shapes at K taus.
    """
    tau = np.asarray(tau, float)
    if np.ndim(ratio) == 0 and (not np.isfinite(ratio) or ratio <= 0):
        return np.ones_like(tau)
    q2 = np.asarray(q2, float)

    def x(t: np.ndarray) -> np.ndarray:  # increment variance over t, in units of the squared step 12 Q^2
        drift = np.where(q2 > 0, slow.mean_square(t) * t ** 2 / np.where(q2 > 0, q2, 1.0), 0.0) if slow is not None \
            else 0.0
        return (ratio * t + drift) / 12.0

    rho = _sawtooth_correlation(np.stack([x(tau), x(2.0 * tau)]))
    return np.clip(1.0 - 4.0 / 3.0 * rho[0] + rho[1] / 3.0, 0.0, 1.0)


@dataclass(frozen=True)
class NoiseTerm:
    """One fitted term: value (SI, NaN = not observed), 95 % interval, dominating tau range (s)."""

    name: str
    value: float
    ci95: tuple[float, float]
    observed: bool
    tau_range: tuple[float, float] | None


@dataclass(frozen=True)
class ChannelNoise:
    """Noise terms of one channel, the fitted model and the classic read-offs (SI).

    ``terms`` by name (:data:`TERMS`); ``theta`` (5,) fitted squared coefficients (0 outside the
    model); ``chi2_red`` reduced weighted chi-squared of the fit; ``read_off`` classic values
    ``white`` (at tau = 1 s), ``rrw`` (at tau = 3 s), ``bias_instability`` (min / 0.664), NaN
    where the curve shows no such slope.
    """

    column: str
    terms: dict[str, NoiseTerm]
    theta: np.ndarray
    chi2_red: float
    read_off: dict[str, float]
    quantization_ratio: float = np.inf  # N^2 / Q^2 (1/s) of the quantization shape (inf: IEEE form)
    slow_rate: SlowRate | None = None  # the record's slow rate in the quantization shape (None: white only)

    def design(self, tau: np.ndarray) -> np.ndarray:
        """The fitted model's basis (K, 5) at taus (s), quantization shape included."""
        return basis(tau, self.quantization_ratio, self.slow_rate, float(self.theta[0]))

    def model_adev(self, tau: np.ndarray) -> np.ndarray:
        """ADEV of the fitted model at taus (s)."""
        return np.sqrt(self.design(tau) @ self.theta)


_X_RANGE = (1e-4, 2.0)  # x = N^2 tau_min / (12 Q^2) at the ends of the searched quantization shapes:
# above 2 the shape h is 1 within 1e-17 at every tau (the IEEE form), below 1e-4 h ~ 0 at the first taus
_SHAPES_PER_DECADE = 3  # log grid of the shape search, refined by Brent's method around its best point
_SLOW_PASSES = 2  # fits with the slow rate estimated from the previous one (M / Q^2 moves Q by ~1 %: 2 suffice)
_LOG_R_TOL = 1e-2  # Brent's tolerance on ln(N^2 / Q^2) (the deviance is then within ~1e-3 of the 1-D minimum)


@dataclass(frozen=True)
class _Fit:
    """One model of the quantization-shape family fitted to the points: ``theta`` (5,), ``ratio`` = N^2 / Q^2
    of its shape (inf: IEEE form), ``dev`` its deviance, ``model`` (K,) its AVAR."""

    dev: float
    theta: np.ndarray
    ratio: float
    model: np.ndarray


def _unpack(c: np.ndarray, has_q: bool, q_fixed: float | None, has_n: bool, n_fixed: float | None,
            fixed: dict[int, float]) -> tuple[float, float, np.ndarray]:
    """(q, n, coefficients of terms 2-4) from the IRLS's free coefficients ``c``, in the order of
    :meth:`_Family._linear`'s columns (q, n when free and present, then the free terms of 2-4)."""
    it = iter(c)
    q = (next(it) if q_fixed is None else q_fixed) if has_q else 0.0
    n = (next(it) if n_fixed is None else n_fixed) if has_n else 0.0
    rest = np.array([fixed[j] if j in fixed else next(it) for j in (2, 3, 4)])
    return float(q), float(n), rest


class _Family:
    """The five-term AVAR model of one channel with the quantization shape h(tau; r) tied to the terms.

    The shape depends on r = N^2 / Q^2 (:func:`quantization_shape`), so a model with quantization and
    white noise is ``Q^2 (3 h(tau; r) / tau^2 + r / tau) + B, K, R terms`` with r a parameter: for a
    given r it is linear and non-negative in (Q^2, B^2, K^2, R^2), and r is found by a 1-D search (a
    log grid of x = r tau_min / 12 over :data:`_X_RANGE` refined by Brent's method). Two more shapes
    complete the family: :meth:`ieee`, every r above the grid's top, where h = 1 and the model is
    the IEEE 952 one with N^2 >= r_top Q^2 (Q = 0 included: ratio inf), and :meth:`no_white`,
    quantization without white noise (N = 0, h = 1, ratio inf). A search over r finds the family's
    best model where the fixed point "h from the last fit's N^2 / Q^2" need not converge (the
    deviance has several local minima in r); every profile point and every model of the
    selection is refitted over r too, so the intervals count the shape's freedom.
    """

    def __init__(self, tau: np.ndarray, avar: np.ndarray, edf: np.ndarray) -> None:
        self.tau, self.avar, self.edf = tau, avar, edf
        self.plain = basis(tau)  # h = 1
        scale = 12.0 / float(tau.min())
        self.r_top = _X_RANGE[1] * scale
        n = int(np.ceil(np.log10(_X_RANGE[1] / _X_RANGE[0]) * _SHAPES_PER_DECADE)) + 1
        self.log_r = np.linspace(np.log(_X_RANGE[0] * scale), np.log(self.r_top), n)
        self.r_grid = [float(np.exp(lr)) for lr in self.log_r]
        self._columns: dict[float, np.ndarray] = {}
        self._held_parts: dict[tuple, tuple[tuple[int, ...], np.ndarray, np.ndarray]] = {}
        self.slow: SlowRate | None = None
        self.q2_ref = 0.0

    def set_slow(self, slow: SlowRate | None, q2_ref: float) -> None:
        """Shape the quantization term with the record's slow rate ``slow``; M / Q^2 uses the Q^2 a model
        holds (a profile point of Q, or N^2 / r for one of N) or else ``q2_ref`` (u^2 s^2, the last full fit's)."""
        self.slow, self.q2_ref = slow, q2_ref
        self._columns.clear()

    def _irls(self, cols: np.ndarray, offset: np.ndarray, start: np.ndarray,
              cutoff: float = np.inf) -> tuple[np.ndarray, np.ndarray, float]:
        """Non-negative c minimising the deviance of ``offset + cols @ c`` (IRLS from the weights of the
        model ``start`` (K,)): (c, model, deviance).

        Stops when the model moves by less than :data:`_IRLS_STEP` of each point's own standard
        deviation (the deviance is then within ~K _IRLS_STEP^2 of its minimum), or when the
        deviance, extrapolated from its last two decreases (IRLS converges linearly), stays above
        ``cutoff``: such a model is no candidate, and its deviance is returned as it is then.
        """
        from workbench.analysis.allan_fit_kernels import irls

        return irls(cols, np.ascontiguousarray(offset), np.ascontiguousarray(start), self.avar, self.edf, float(cutoff), _IRLS_ITER, _IRLS_STEP, CORRELATION)

    def _held(self, fixed: dict[int, float]) -> tuple[tuple[int, ...], np.ndarray, np.ndarray]:
        """Terms 2-4 under ``fixed``: (the free ones, their IEEE columns (K, f), the AVAR (K,) of the held ones),
        kept for the next calls (a search fits a dozen shapes with the same terms held)."""
        key = tuple((j, fixed[j]) for j in (2, 3, 4) if j in fixed)
        if key not in self._held_parts:
            if len(self._held_parts) > 64:
                self._held_parts.clear()
            offset = np.zeros(len(self.tau))
            for j, value in key:
                offset = offset + value * self.plain[:, j]
            free = tuple(j for j in (2, 3, 4) if j not in fixed)
            self._held_parts[key] = (free, self.plain[:, list(free)], offset)
        return self._held_parts[key]

    def _linear(self, q_col: np.ndarray | None, q_fixed: float | None, n_col: np.ndarray | None,
                n_fixed: float | None, fixed: dict[int, float], start: np.ndarray,
                cutoff: float) -> tuple[float, float, float, np.ndarray, np.ndarray]:
        """Fit with the quantization and white parts given as a column each (None: absent) or a fixed
        coefficient, and terms 2-4 free unless in ``fixed``: (q, n, deviance, coefficients of 2-4, model);
        ``cutoff`` as :meth:`_irls`."""
        lead = [col for col, value in ((q_col, q_fixed), (n_col, n_fixed)) if col is not None and value is None]
        free, free_cols, offset = self._held(fixed)
        for col, value in ((q_col, q_fixed), (n_col, n_fixed)):
            if col is not None and value is not None:
                offset = value * col + offset
        cols = np.empty((len(self.tau), len(lead) + len(free)))
        for i, col in enumerate(lead):
            cols[:, i] = col
        cols[:, len(lead):] = free_cols
        c, model, dev = self._irls(cols, offset, start, cutoff)
        q, n, rest = _unpack(c, q_col is not None, q_fixed, n_col is not None, n_fixed, fixed)
        return q, n, dev, rest, model

    def shaped(self, log_r: float, fixed: dict[int, float], start: np.ndarray, cutoff: float = np.inf) -> _Fit:
        """Best model with N^2 = r Q^2 (r = exp(log_r)) and the terms in ``fixed`` held."""
        r = float(np.exp(log_r))
        q_fixed = fixed[0] if 0 in fixed else (fixed[1] / r if 1 in fixed else None)
        col = self._shape_column(log_r, r, q_fixed)
        q, _, dev, rest, model = self._linear(col, q_fixed, None, None, fixed, start, cutoff)
        return _Fit(dev, np.array([q, r * q, *rest]), r, model)

    def _shape_column(self, log_r: float, r: float, q_fixed: float | None) -> np.ndarray:
        """The AVAR per Q^2 (K,) of quantization and white noise with N^2 = r Q^2 (r = exp(log_r)), the
        quantization shape's slow rate taken with the Q^2 held ``q_fixed`` (None: the last full fit's)."""
        held = self.slow is not None and q_fixed is not None  # the shape depends on the Q^2 held
        col = None if held else self._columns.get(log_r)
        if col is None:
            q2 = q_fixed if held else self.q2_ref
            col = self.plain[:, 0] * quantization_shape(self.tau, r, self.slow, q2) + r * self.plain[:, 1]  # per Q^2
            if not held and len(self._columns) < 4 * len(self.log_r):  # grid columns are reused by every search
                self._columns[log_r] = col
        return col

    def _grid(self, fixed: dict[int, float], start: np.ndarray, cutoff: float, lowest: float
              ) -> tuple[np.ndarray, Callable[[int], _Fit]]:
        """:meth:`shaped` at every grid point in one compiled loop, each point's cutoff ``min(cutoff, lowest)``
        with ``lowest`` lowered by every deviance found: (deviances (G,), the fit of a grid point by index)."""
        from workbench.analysis.allan_fit_kernels import irls_grid

        q_fixed = [fixed[0] if 0 in fixed else (fixed[1] / r if 1 in fixed else None) for r in self.r_grid]
        if self.slow is not None and q_fixed[0] is not None:  # shapes of the Q^2 held: all in one evaluation
            r = np.array(self.r_grid)[:, None]
            cols = self.plain[:, 0] * quantization_shape(self.tau, r, self.slow, np.array(q_fixed)[:, None]) \
                + r * self.plain[:, 1]
        else:
            cols = np.array([self._shape_column(lr, r, qf) for lr, r, qf in zip(self.log_r, self.r_grid, q_fixed)])
        free, free_cols, held = self._held(fixed)
        if q_fixed[0] is None:
            lead, offsets = cols, np.broadcast_to(held, cols.shape)
        else:
            lead, offsets = cols[:, :0], np.array([qf * col + held for qf, col in zip(q_fixed, cols)])
        devs, c, models = irls_grid(np.ascontiguousarray(lead), np.ascontiguousarray(offsets),
                                    np.ascontiguousarray(free_cols), np.ascontiguousarray(start), self.avar, self.edf,
                                    float(cutoff), float(lowest), _IRLS_ITER, _IRLS_STEP, CORRELATION)

        def fit(g: int) -> _Fit:
            q, _, rest = _unpack(c[g], True, q_fixed[g], False, None, fixed)
            r = self.r_grid[g]
            return _Fit(float(devs[g]), np.array([q, r * q, *rest]), r, models[g])

        return devs, fit

    def ieee(self, fixed: dict[int, float], start: np.ndarray, cutoff: float = np.inf) -> _Fit:
        """Best model with h = 1 and N^2 >= r_top Q^2 (N^2 = r_top Q^2 + n, n >= 0)."""
        p = self.plain
        if 1 in fixed and 0 not in fixed:  # N^2 held: Q^2 free up to N^2 / r_top
            q, _, dev, rest, model = self._linear(p[:, 0], None, p[:, 1], fixed[1], fixed, start, cutoff)
            if q > fixed[1] / self.r_top:  # the bound is active: that model is the grid's top shape
                dev = float("inf")
            n2 = fixed[1]
        else:
            q_fixed = fixed.get(0)
            n_fixed = None if 1 not in fixed else fixed[1] - self.r_top * fixed[0]
            if n_fixed is not None and n_fixed < 0:
                return _Fit(float("inf"), np.zeros(5), np.inf, start)
            q, n, dev, rest, model = self._linear(p[:, 0] + self.r_top * p[:, 1], q_fixed, p[:, 1], n_fixed, fixed,
                                                  start, cutoff)
            n2 = self.r_top * q + n
        ratio = n2 / q if q > 0 and n2 > 0 else np.inf
        return _Fit(dev, np.array([q, n2, *rest]), ratio, model)

    def no_white(self, fixed: dict[int, float], start: np.ndarray, cutoff: float = np.inf) -> _Fit:
        """Best model with quantization (h = 1) and no white noise."""
        if fixed.get(1, 0.0) > 0:
            return _Fit(float("inf"), np.zeros(5), np.inf, start)
        q, _, dev, rest, model = self._linear(self.plain[:, 0], fixed.get(0), None, None, fixed, start, cutoff)
        return _Fit(dev, np.array([q, 0.0, *rest]), np.inf, model)

    def best(self, fixed: dict[int, float], start: np.ndarray, cutoff: float = np.inf) -> _Fit:
        """The family's best model with the terms ``fixed`` {index: squared value} held (the others >= 0),
        IRLS from the weights of the model ``start`` (K,). A deviance above ``cutoff`` may be returned
        unconverged (an overestimate): the callers only need to know it is above."""
        fits = [self.ieee(fixed, start, cutoff), self.no_white(fixed, start, cutoff)]
        if fixed.get(0, 1.0) > 0 and fixed.get(1, 1.0) > 0 and not (0 in fixed and 1 in fixed):
            devs, grid_fit = self._grid(fixed, start, cutoff, min(f.dev for f in fits))
            i = int(np.argmin(devs))
            top = grid_fit(i)  # the grid's first lowest: the one min() over the points in order would keep
            fits.append(top)
            lo, hi = self.log_r[max(i - 1, 0)], self.log_r[min(i + 1, len(self.log_r) - 1)]
            if np.isfinite(top.dev) and top.dev <= min(f.dev for f in fits):
                found: dict[float, _Fit] = {}

                def dev_at(lr: float) -> float:
                    found[lr] = self.shaped(lr, fixed, top.model, cutoff)
                    return found[lr].dev

                lr, _ = minimize_bounded(dev_at, lo, hi, xtol=_LOG_R_TOL)
                fits.append(found[lr])
        return min(fits, key=lambda f: f.dev)


@lru_cache(maxsize=8)
def _chi2_1(level: float) -> float:
    """chi2(level, 1), the likelihood-ratio threshold of one term (3.84 at 0.95; ~3 ms a call, made per interval)."""
    return float(chi2_ppf(level, 1))


def profile_interval(family: _Family, k: int, full: _Fit, t_cap: float, level: float = 0.95) -> tuple[float, float]:
    """Profile-likelihood interval (lo, hi) of theta_k over the whole model family.

    The set of theta_k whose profile deviance (the other terms and the quantization shape refitted,
    all terms non-negative) lies within chi2(level, 1) of the global minimum of the full fit
    ``full``; independent of which model the selection picked (an interval of the selected model
    alone would inherit the selection's optimism). ``t_cap`` is where the search for the upper
    limit starts (it grows by 4 until the profile exceeds the threshold).
    """
    limit = full.dev + _chi2_1(level)
    t_hat = float(full.theta[k])
    seen: dict[float, float] = {}

    def excess(t: float) -> float:
        if t not in seen:
            seen[t] = family.best({k: t}, full.model, limit + 1.0).dev - limit
        return seen[t]

    top = max(t_cap, t_hat * 2.0, 1e-300)
    for _ in range(60):
        if excess(top) > 0:
            break
        top *= 4.0
    tol = 1e-7 * top  # absolute tolerance scaled to the term (a fixed 2e-12 is larger than a squared term)
    lo = 0.0
    if t_hat > 0 and excess(0.0) > 0:
        lo = root_bracket(excess, 0.0, t_hat, xtol=tol, rtol=1e-5) if excess(t_hat) < 0 else t_hat
    base = t_hat if excess(t_hat) < 0 else 0.0
    hi = root_bracket(excess, base, top, xtol=tol, rtol=1e-5) if excess(base) < 0 else top
    return lo, hi


def _select(family: _Family, full: _Fit) -> list[int]:
    """Terms the data show: backward elimination from the full model by likelihood ratio.

    Starting from the terms of the full fit that are non-zero, the term whose removal (the others
    and the quantization shape refitted) raises the deviance least is dropped while that rise is
    below chi2(0.95, 1) = 3.84; the remaining terms are "observed". At least one term always stays.
    """
    cols = [k for k in range(5) if full.theta[k] > 0]
    dropped = {k: 0.0 for k in range(5) if k not in cols}
    d_cur = full.dev
    while len(cols) > 1:
        rises = [(family.best({**dropped, k: 0.0}, full.model, d_cur + 4.0).dev - d_cur, k) for k in cols]
        rise, k = min(rises)
        if rise >= _chi2_1(0.95):
            break
        cols.remove(k)
        dropped[k] = 0.0
        d_cur += rise
    return cols


def _dominant_range(k: int, theta: np.ndarray, tau_lo: float, tau_hi: float,
                    ratio: float = np.inf, slow: SlowRate | None = None) -> tuple[float, float] | None:
    """Tau range (s) within [tau_lo, tau_hi] where term k is the largest model contribution."""
    grid = np.logspace(np.log10(tau_lo), np.log10(tau_hi), 400)
    parts = basis(grid, ratio, slow, float(theta[0])) * theta
    top = (np.argmax(parts, axis=1) == k) & (parts[:, k] > 0)
    return (float(grid[top].min()), float(grid[top].max())) if top.any() else None


def _fit_family(tau: np.ndarray, avar: np.ndarray, edf: np.ndarray,
                mean_square: tuple[float, float] | None) -> tuple[_Family, _Fit]:
    """The model family of the points and its best full model: with quantization found and the record's
    ``mean_square`` (as :func:`fit_channel`) given, the slow rate estimated from the fitted N, Q, B and the
    family refitted with it, :data:`_SLOW_PASSES` times (M / Q^2 with the previous pass's Q)."""
    family = _Family(tau, avar, edf)
    full = family.best({}, avar)
    if mean_square is None or not (full.theta[0] > 0 and np.isfinite(full.ratio)):
        return family, full
    for _ in range(_SLOW_PASSES):
        family.set_slow(SlowRate.from_record(*mean_square, *full.theta[[1, 0, 2]]), float(full.theta[0]))
        full = family.best({}, full.model)
        if not (full.theta[0] > 0 and np.isfinite(full.ratio)):  # the shape gave quantization up: none
            family.set_slow(None, 0.0)
            return family, family.best({}, avar)
    return family, full


def fit_channel(tau: np.ndarray, dev: np.ndarray, edf: np.ndarray, hi: np.ndarray, column: str = "",
                mean_square: tuple[float, float] | None = None) -> ChannelNoise:
    """Fit the IEEE 952 terms to one channel's ADEV ``dev`` (K,) at ``tau`` (K,) s.

    ``edf`` (K,) equivalent degrees of freedom and ``hi`` (K,) upper 95 % ADEV limits, as in
    :class:`workbench.analysis.allan_ci.DeviationCI`. Units: SI of the input rate.
    ``mean_square`` (W s, u^2): the record's mean square of its rate (mean included) averaged over W
    (:func:`rate_mean_square`); with quantization it gives the slow rate of the shape (:class:`SlowRate`).
    """
    ok = np.isfinite(dev) & (dev > 0) & np.isfinite(edf) & (edf > 0)
    tau, avar, edf, hi = tau[ok], dev[ok] ** 2, edf[ok], hi[ok]
    if len(tau) == 0:
        raise ValueError(f"{column}: no noise model fits the Allan curve")
    family, full = _fit_family(tau, avar, edf, mean_square)
    ratio = full.ratio
    plain = family.plain  # the IEEE 952 basis (h = 1) of the search starts
    intervals = []
    for k in range(5):
        # the smallest single-point 97.5 % bound: a start for the search of the upper limit
        cap = float(np.min(hi ** 2 / plain[:, k]))
        intervals.append(profile_interval(family, k, full, cap))
    cols = _select(family, full)
    theta = np.where(np.isin(np.arange(5), cols), full.theta, 0.0)
    w = edf / (2.0 * full.model ** 2)
    chi2_red = float(np.sum(w * (avar - full.model) ** 2) / max(len(tau) - len(cols), 1))
    terms: dict[str, NoiseTerm] = {}
    for k, name in enumerate(TERMS):
        lo, up = intervals[k]
        if k in cols:
            terms[name] = NoiseTerm(name, float(np.sqrt(full.theta[k])), (float(np.sqrt(lo)), float(np.sqrt(up))), True,
                                    _dominant_range(k, theta, float(tau.min()), float(tau.max()), ratio, family.slow))
        else:
            terms[name] = NoiseTerm(name, float("nan"), (0.0, float(np.sqrt(up))), False, None)
    return ChannelNoise(column, terms, theta, chi2_red, read_offs(tau, np.sqrt(avar)), ratio, family.slow)


def read_offs(tau: np.ndarray, dev: np.ndarray) -> dict[str, float]:
    """Classic read-offs from an ADEV curve (SI): ``white`` = the slope -1/2 line at 1 s, ``rrw`` =
    the slope +1/2 line at 3 s, ``bias_instability`` = min ADEV / 0.664.

    Each line goes through the point whose local log-log slope is nearest the line's slope;
    a slope farther than 0.25 from it means the curve shows no such region (NaN).
    """
    lt, ld = np.log(tau), np.log(dev)
    slope = np.gradient(ld, lt)
    out = {"bias_instability": float(dev.min() / np.sqrt(FLICKER))}
    for name, target, at in (("white", -0.5, 1.0), ("rrw", 0.5, 3.0)):
        k = int(np.argmin(np.abs(slope - target)))
        out[name] = float(dev[k] * (at / tau[k]) ** target) if abs(slope[k] - target) < 0.25 \
            else float("nan")
    return out


def fit_terms(ci: DeviationCI, mean_square: tuple[float, np.ndarray] | None = None) -> tuple[ChannelNoise, ...]:
    """Fit every channel of an overlapping-ADEV curve with intervals (``ci.curve.kind == 'oadev'``);
    ``mean_square`` (W s, (C,) u^2) as :func:`rate_mean_square` returns it, for the quantization shape."""
    if ci.curve.kind != "oadev":
        raise ValueError(f"noise-term fit needs an overlapping Allan deviation, not {ci.curve.kind}")
    c = ci.curve
    return tuple(fit_channel(c.tau, c.dev[:, j], ci.edf[:, j], ci.hi[:, j], col,
                             None if mean_square is None else (mean_square[0], float(mean_square[1][j])))
                 for j, col in enumerate(c.columns))


def slow_window(m: np.ndarray, rate: float, n_samples: int) -> int | None:
    """Index into the averaging factors ``m`` of the window for :func:`rate_mean_square`: the longest
    m / rate up to :data:`SLOW_WINDOW_S` with at least :data:`SLOW_MIN_WINDOWS` windows in ``n_samples``
    (None: the record is too short)."""
    ok = np.flatnonzero((m <= SLOW_WINDOW_S * rate) & (m * SLOW_MIN_WINDOWS <= n_samples))
    return int(ok[-1]) if len(ok) else None


def rate_mean_square(z: np.ndarray, m: int, rate: float, mean: np.ndarray) -> tuple[float, np.ndarray]:
    """(W, mean square (C,)) of the rate averaged over consecutive windows of W = m / rate s, mean included:
    from ``z`` (C, J) the mean-removed phase decimated by m, ``x[:, ::m]`` (:func:`workbench.analysis.allan.phase`,
    u*s) and ``mean`` (C,) the rate's mean (u). Units u^2 of the rate."""
    w = m / rate
    return w, np.mean((np.diff(z, axis=1) / w + np.asarray(mean, float)[:, None]) ** 2, axis=1)


# -- a whole record ------------------------------------------------------------------------

def analyze_record(y: np.ndarray, rate: float, columns: tuple[str, ...] | list[str], quantity: str | None = None,
                   taus: str | np.ndarray = "octave", gap_policy: str = "error", source: str = "data",
                   overwrite: bool = False) -> AllanAnalysis:
    """OADEV with 95 % intervals and the IEEE 952 fit of rate samples ``y`` (N, C), SI, at ``rate`` Hz.

    ``quantity`` (``"gyro"`` | ``"accel"``) enables the unit plausibility check and names the
    calibration-set terms; ``taus`` and ``gap_policy`` as :func:`workbench.analysis.allan.deviation`
    (with gaps, noise identification uses the longest gap-free run). ``overwrite``: ``y`` may be
    replaced by its phase when it is a :func:`workbench.analysis.allan.rate_buffer` view (no second
    full-size array; ``y`` is garbage afterwards).
    """
    from workbench.analysis import allan
    from workbench.analysis.allan_ci import confidence

    segments, warnings = allan.prepare_rate_data(y, tuple(columns), source, gap_policy, quantity)
    mean = np.mean(max(segments, key=len), axis=0)  # before the phase may overwrite the samples
    # compiled sums whatever the length: the fit loads numba anyway (allan_fit_kernels)
    curve, x = allan.segment_deviation(segments, rate, "oadev", taus, tuple(columns), source, overwrite, True)
    ci = confidence(curve, x, source=source)
    k = slow_window(curve.m, rate, x.shape[1] - 1)
    mk = None if k is None else int(curve.m[k])
    ms = None if mk is None else rate_mean_square(x[:, ::mk][:, :MAX_POINTS_ID], mk, rate, mean)
    return AllanAnalysis(ci, fit_terms(ci, ms), quantity, tuple(warnings))


def analyze_stream(batches: Callable[[], Iterator[np.ndarray]], rate: float, columns: tuple[str, ...] | list[str],
                   quantity: str | None = None, taus: str | np.ndarray = "octave", source: str = "stream",
                   tmp_dir: str | Path | None = None) -> AllanAnalysis:
    """:func:`analyze_record` of a record too large for memory, in bounded memory.

    ``batches()`` returns a fresh iterator over consecutive (n, C) blocks of SI rate samples at
    ``rate`` Hz (e.g. ``lambda: session.stream(cols, step)``); the record must be gap-free. The
    deviations come from :func:`workbench.analysis.allan_stream.stream_deviation_from`; the noise
    identification uses the phase decimated by each m, of which the in-memory path reads only
    the first :data:`workbench.analysis.allan_ci.MAX_POINTS_ID` points: the streamed pass keeps
    exactly those (at most 0.5 MB per tau and channel), so intervals and terms are those of
    :func:`analyze_record` (up to the ~1e-13 summation-order differences of the deviations).
    """
    from workbench.analysis.allan_ci import confidence, identify_decimated
    from workbench.analysis.allan_stream import stream_deviation_from

    s = stream_deviation_from(batches, columns, rate, "oadev", taus, tmp_dir=tmp_dir, source=source,
                              quantity=quantity, keep=MAX_POINTS_ID)
    c = s.curve
    ci = confidence(c, alpha=identify_decimated(s.decimated, c.n_samples + 1, c.m, c.kind), source=source)
    k = slow_window(c.m, rate, c.n_samples)
    ms = None if k is None else rate_mean_square(s.decimated[k], int(c.m[k]), rate, s.mean)
    return AllanAnalysis(ci, fit_terms(ci, ms), quantity)
