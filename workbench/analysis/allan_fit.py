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
first tau). The fit iterates h with the fitted N^2 / Q^2. For the virtual sensor's
quantizer it matches the simulated AVAR within 0.6 % at every tau (benchmarks/allan_coverage.py).

The model is linear in the squared coefficients theta (for a given h). Each AVAR
point is a scaled chi-squared variable with the Greenhall EDF, so the fit maximises the gamma
likelihood (non-negative IRLS with weights edf / model^2, the identity-link gamma GLM); its
deviance is divided by :data:`CORRELATION` (neighbouring overlapping points share about half
their information).

Values and intervals come from the full five-term fit: a term's 95 % interval is the set of
values whose profile deviance (the other four terms refitted, all non-negative) lies within
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
from pathlib import Path

import numpy as np

from workbench.allan_model import FLICKER_AVAR, avar_basis
from workbench.analysis.allan_ci import DeviationCI, chi2_ppf
from workbench.analysis.allan_report import CALSET_NAMES, AllanAnalysis  # noqa: F401 (re-exported)
from workbench.analysis.allan_terms import TERMS
from workbench.analysis.small_solvers import nnls, root_bracket

FLICKER = FLICKER_AVAR  # AVAR per B^2; ADEV floor 0.664 B (workbench.allan_model)
CORRELATION = 2.0  # overlapping AVAR points at octave taus share about half their information:
# weighted chi-squared differences are divided by this before model comparison
_IRLS_ITER = 30


def basis(tau: np.ndarray, ratio: float = np.inf) -> np.ndarray:
    """AVAR basis (K, 5) at taus (s): 3 h/tau^2, 1/tau, 2 ln2/pi, tau/3, tau^2/2 (:func:`workbench.allan_model.avar_basis`),
    with the quantization shape h of :func:`quantization_shape` for ``ratio`` = N^2 / Q^2 (1/s; inf: h = 1)."""
    a = avar_basis(np.atleast_1d(np.asarray(tau, float)))
    if np.isfinite(ratio):
        a[:, 0] *= quantization_shape(a[:, 1] ** -1, ratio)
    return a


def _sawtooth_correlation(x: np.ndarray) -> np.ndarray:
    """Correlation of ``S mod q`` at two instants whose integral increment has variance ``x q^2``:
    (6 / pi^2) sum_n n^-2 exp(-2 pi^2 n^2 x); the small-x form pi^2/6 - sqrt(pi a) + a/2 of the sum
    (a = 2 pi^2 x) is exact to ~1e-9 below a = 0.5, the series is cut at n = 24 above it."""
    a = 2.0 * np.pi ** 2 * np.maximum(np.asarray(x, float), 0.0)
    small = a < 0.5
    n = np.arange(1, 25, dtype=float)[:, None]
    series = np.sum(np.exp(-(n ** 2) * np.where(small, 1.0, a).ravel()[None, :]) / n ** 2, axis=0).reshape(a.shape)
    total = np.where(small, np.pi ** 2 / 6.0 - np.sqrt(np.pi * a) + a / 2.0, series)
    return 6.0 / np.pi ** 2 * total


def quantization_shape(tau: np.ndarray, ratio: float) -> np.ndarray:
    """h(tau) in [0, 1] of the quantization term ``3 Q^2 h / tau^2`` beside white noise N (module docstring).

    ``ratio`` = N^2 / Q^2 (1/s; N u/sqrt(Hz), Q u*s); inf gives the IEEE 952 form h = 1 and 0
    (no white noise) the same, since then nothing moves the integral between steps but the slow terms.
    """
    tau = np.asarray(tau, float)
    if not np.isfinite(ratio) or ratio <= 0:
        return np.ones_like(tau)
    x = ratio * tau / 12.0
    return np.clip(1.0 - 4.0 / 3.0 * _sawtooth_correlation(x) + _sawtooth_correlation(2.0 * x) / 3.0, 0.0, 1.0)


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

    def design(self, tau: np.ndarray) -> np.ndarray:
        """The fitted model's basis (K, 5) at taus (s), quantization shape included."""
        return basis(tau, self.quantization_ratio)

    def model_adev(self, tau: np.ndarray) -> np.ndarray:
        """ADEV of the fitted model at taus (s)."""
        return np.sqrt(self.design(tau) @ self.theta)


def _irls(a: np.ndarray, avar: np.ndarray, edf: np.ndarray, cols: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Non-negative fit of avar on basis columns ``cols``, weights from the model; (theta(5,), w)."""
    model = avar.copy()
    theta = np.zeros(5)
    for _ in range(_IRLS_ITER):
        w = edf / (2.0 * np.maximum(model, 1e-300) ** 2)
        sw = np.sqrt(w)
        coef, _ = nnls(a[:, cols] * sw[:, None], avar * sw)
        new = np.zeros(5)
        new[cols] = coef
        model = a @ new
        done = float(np.max(np.abs(new - theta))) <= 1e-8 * float(np.max(new))
        theta = new
        if done or not model.max() > 0:
            break
    return theta, edf / (2.0 * np.maximum(model, 1e-300) ** 2)


def deviance(a: np.ndarray, avar: np.ndarray, edf: np.ndarray, theta: np.ndarray) -> float:
    """Deviance of the model ``a @ theta`` for AVAR points ``avar`` with ``edf`` degrees of freedom.

    Each point is a scaled chi-squared variable, avar_k ~ model_k chi2(edf_k) / edf_k; minus twice
    its log-likelihood, up to a constant, is edf_k (r_k - 1 - ln r_k) with r_k = avar_k / model_k
    (the gamma deviance). Divided by :data:`CORRELATION` for the information neighbouring
    overlapping points share. The non-negative IRLS of :func:`_irls` minimises it.
    """
    model = a @ theta
    if not np.all(model > 0):
        return float("inf")
    r = avar / model
    return float(np.sum(edf * (r - 1.0 - np.log(r)))) / CORRELATION


def _profile(a: np.ndarray, avar: np.ndarray, edf: np.ndarray, k: int, t: float, start: np.ndarray,
             design_of: Callable[[np.ndarray], np.ndarray] | None = None) -> float:
    """Deviance of the best non-negative model with theta_k fixed at ``t`` (the other four free),
    iterated from the weights of the model ``start`` (5,) with its k-th term set to ``t``.
    ``design_of(theta)``: the basis when it depends on theta (the quantization shape), else ``a``."""
    cols = [c for c in range(5) if c != k]
    theta = start.copy()
    theta[k] = t
    if design_of is not None:
        a = design_of(theta)
    model = np.maximum(a @ theta, 1e-300)
    for _ in range(_IRLS_ITER):
        rest = avar - t * a[:, k]
        with np.errstate(over="ignore", invalid="ignore"):  # far profile points overflow the weights
            sw = np.sqrt(edf) / np.maximum(model, 1e-300)
            lhs, rhs = a[:, cols] * sw[:, None], rest * sw
        coef, _ = nnls(lhs, rhs)
        new = np.zeros(5)
        new[cols] = coef
        new[k] = t
        if design_of is not None:
            a = design_of(new)
        model = a @ new
        done = float(np.max(np.abs(new - theta))) <= 1e-6 * float(np.max(new))
        theta = new
        if done:
            break
    return deviance(a, avar, edf, theta)


def profile_interval(a: np.ndarray, avar: np.ndarray, edf: np.ndarray, k: int, full: np.ndarray, d_min: float,
                     t_cap: float, level: float = 0.95,
                     design_of: Callable[[np.ndarray], np.ndarray] | None = None) -> tuple[float, float]:
    """Profile-likelihood interval (lo, hi) of theta_k over all non-negative five-term models.

    The set of theta_k whose profile deviance lies within chi2(level, 1) of the global minimum
    ``d_min`` of the full fit ``full`` (5,); independent of which model the selection picked (an
    interval of the selected model alone would inherit the selection's optimism). ``t_cap`` is
    where the search for the upper limit starts (it grows by 4 until the profile exceeds the
    threshold). ``design_of`` as :func:`_profile`.
    """
    limit = d_min + chi2_ppf(level, 1)
    t_hat = float(full[k])

    def excess(t: float) -> float:
        return _profile(a, avar, edf, k, t, full, design_of) - limit

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


def _select(a: np.ndarray, avar: np.ndarray, edf: np.ndarray, full: np.ndarray) -> list[int]:
    """Terms the data show: backward elimination from the full model by likelihood ratio.

    Starting from the terms of the full fit that are non-zero, the term whose removal (the others
    refitted) raises the deviance least is dropped while that rise is below chi2(0.95, 1) = 3.84;
    the remaining terms are "observed". At least one term always stays.
    """
    cols = [k for k in range(5) if full[k] > 0]
    d_cur = deviance(a, avar, edf, full)
    while len(cols) > 1:
        rises = []
        for k in cols:
            rest = [c for c in cols if c != k]
            theta, _ = _irls(a, avar, edf, rest)
            rises.append((deviance(a, avar, edf, theta) - d_cur, k))
        rise, k = min(rises)
        if rise >= chi2_ppf(0.95, 1):
            break
        cols.remove(k)
        d_cur += rise
    return cols


def _dominant_range(k: int, theta: np.ndarray, tau_lo: float, tau_hi: float,
                    ratio: float = np.inf) -> tuple[float, float] | None:
    """Tau range (s) within [tau_lo, tau_hi] where term k is the largest model contribution."""
    grid = np.logspace(np.log10(tau_lo), np.log10(tau_hi), 400)
    parts = basis(grid, ratio) * theta
    top = (np.argmax(parts, axis=1) == k) & (parts[:, k] > 0)
    return (float(grid[top].min()), float(grid[top].max())) if top.any() else None


def fit_channel(tau: np.ndarray, dev: np.ndarray, edf: np.ndarray, hi: np.ndarray, column: str = "") -> ChannelNoise:
    """Fit the IEEE 952 terms to one channel's ADEV ``dev`` (K,) at ``tau`` (K,) s.

    ``edf`` (K,) equivalent degrees of freedom and ``hi`` (K,) upper 95 % ADEV limits, as in
    :class:`workbench.analysis.allan_ci.DeviationCI`. Units: SI of the input rate.
    """
    ok = np.isfinite(dev) & (dev > 0) & np.isfinite(edf) & (edf > 0)
    tau, avar, edf, hi = tau[ok], dev[ok] ** 2, edf[ok], hi[ok]
    if len(tau) == 0:
        raise ValueError(f"{column}: no noise model fits the Allan curve")
    a, full, ratio = _fit_full(tau, avar, edf)
    d_min = deviance(a, avar, edf, full)
    # the quantization shape depends on N^2 / Q^2: every profile refits it with the terms
    shaped = (lambda th: basis(tau, th[1] / th[0] if th[0] > 0 and th[1] > 0 else np.inf)) \
        if np.isfinite(ratio) else None
    plain = basis(tau)  # the IEEE 952 basis (h = 1) of the search starts
    intervals = []
    for k in range(5):
        # the smallest single-point 97.5 % bound: a start for the search of the upper limit
        cap = float(np.min(hi ** 2 / plain[:, k]))
        intervals.append(profile_interval(a, avar, edf, k, full, d_min, cap, design_of=shaped))
    cols = _select(a, avar, edf, full)
    theta = np.where(np.isin(np.arange(5), cols), full, 0.0)
    w = edf / (2.0 * (a @ full) ** 2)
    chi2_red = float(np.sum(w * (avar - a @ full) ** 2) / max(len(tau) - len(cols), 1))
    terms: dict[str, NoiseTerm] = {}
    for k, name in enumerate(TERMS):
        lo, up = intervals[k]
        if k in cols:
            terms[name] = NoiseTerm(name, float(np.sqrt(full[k])), (float(np.sqrt(lo)), float(np.sqrt(up))), True,
                                    _dominant_range(k, theta, float(tau.min()), float(tau.max()), ratio))
        else:
            terms[name] = NoiseTerm(name, float("nan"), (0.0, float(np.sqrt(up))), False, None)
    return ChannelNoise(column, terms, theta, chi2_red, read_offs(tau, np.sqrt(avar)), ratio)


def _fit_full(tau: np.ndarray, avar: np.ndarray, edf: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The full five-term fit with the quantization shape iterated to the fitted N^2 / Q^2:
    (basis, theta (5,), ratio); ratio is inf when the fit has no quantization or no white noise."""
    ratio = np.inf
    a = basis(tau)
    full, _ = _irls(a, avar, edf, list(range(5)))
    for _ in range(20):
        if not (full[0] > 0 and full[1] > 0):
            break
        new = full[1] / full[0]
        a = basis(tau, new)
        full, _ = _irls(a, avar, edf, list(range(5)))
        done = np.isfinite(ratio) and abs(new - ratio) <= 1e-4 * ratio
        ratio = new
        if done:
            break
    if not (full[0] > 0 and full[1] > 0):
        ratio, a = np.inf, basis(tau)
        full, _ = _irls(a, avar, edf, list(range(5)))
    return a, full, ratio


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


def fit_terms(ci: DeviationCI) -> tuple[ChannelNoise, ...]:
    """Fit every channel of an overlapping-ADEV curve with intervals (``ci.curve.kind == 'oadev'``)."""
    if ci.curve.kind != "oadev":
        raise ValueError(f"noise-term fit needs an overlapping Allan deviation, not {ci.curve.kind}")
    c = ci.curve
    return tuple(fit_channel(c.tau, c.dev[:, j], ci.edf[:, j], ci.hi[:, j], col) for j, col in enumerate(c.columns))


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
    curve, x = allan.segment_deviation(segments, rate, "oadev", taus, tuple(columns), source, overwrite)
    ci = confidence(curve, x)
    return AllanAnalysis(ci, fit_terms(ci), quantity, tuple(warnings))


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
    from workbench.analysis.allan_ci import MAX_POINTS_ID, confidence, identify_decimated
    from workbench.analysis.allan_stream import stream_deviation_from

    s = stream_deviation_from(batches, columns, rate, "oadev", taus, tmp_dir=tmp_dir, source=source,
                              quantity=quantity, keep=MAX_POINTS_ID)
    c = s.curve
    ci = confidence(c, alpha=identify_decimated(s.decimated, c.n_samples + 1, c.m, c.kind))
    return AllanAnalysis(ci, fit_terms(ci), quantity)
