"""IEEE Std 952 noise-term fit of an Allan variance curve, with model selection.

Model of the Allan variance of rate data (IEEE Std 952-1997 Annex C, table C.2):

    AVAR(tau) = 3 Q^2 / tau^2 + N^2 / tau + (2 ln2 / pi) B^2 + K^2 tau / 3 + R^2 tau^2 / 2

Q quantization (rad | m/s), N white noise density (ARW rad/s/sqrt(Hz) | VRW m/s^2/sqrt(Hz)),
B bias instability (rad/s | m/s^2), K rate random walk (rad/s^2/sqrt(Hz) | m/s^3/sqrt(Hz)),
R rate ramp (rad/s^2 | m/s^3). The model is linear in the squared coefficients theta. Each AVAR
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
:func:`read_offs`, :class:`AllanAnalysis`, :func:`analyze_record`, :func:`analyze_stream`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from workbench.allan_model import FLICKER_AVAR, avar_basis
from workbench.analysis.allan_ci import DeviationCI, chi2_ppf
from workbench.analysis.small_solvers import nnls, root_bracket

TERMS = ("quantization", "white", "bias_instability", "rrw", "rate_ramp")
FLICKER = FLICKER_AVAR  # AVAR per B^2; ADEV floor 0.664 B (workbench.allan_model)
CORRELATION = 2.0  # overlapping AVAR points at octave taus share about half their information:
# weighted chi-squared differences are divided by this before model comparison
_IRLS_ITER = 30


def basis(tau: np.ndarray) -> np.ndarray:
    """AVAR basis (K, 5) at taus (s): 3/tau^2, 1/tau, 2 ln2/pi, tau/3, tau^2/2 (:func:`workbench.allan_model.avar_basis`)."""
    return avar_basis(np.atleast_1d(np.asarray(tau, float)))


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

    def model_adev(self, tau: np.ndarray) -> np.ndarray:
        """ADEV of the fitted model at taus (s)."""
        return np.sqrt(basis(tau) @ self.theta)


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


def _profile(a: np.ndarray, avar: np.ndarray, edf: np.ndarray, k: int, t: float, start: np.ndarray) -> float:
    """Deviance of the best non-negative model with theta_k fixed at ``t`` (the other four free),
    iterated from the weights of the model ``start`` (5,) with its k-th term set to ``t``."""
    cols = [c for c in range(5) if c != k]
    rest = avar - t * a[:, k]
    theta = start.copy()
    theta[k] = t
    model = np.maximum(a @ theta, 1e-300)
    for _ in range(_IRLS_ITER):
        sw = np.sqrt(edf) / np.maximum(model, 1e-300)
        coef, _ = nnls(a[:, cols] * sw[:, None], rest * sw)
        new = np.zeros(5)
        new[cols] = coef
        new[k] = t
        model = a @ new
        done = float(np.max(np.abs(new - theta))) <= 1e-6 * float(np.max(new))
        theta = new
        if done:
            break
    return deviance(a, avar, edf, theta)


def profile_interval(a: np.ndarray, avar: np.ndarray, edf: np.ndarray, k: int, full: np.ndarray, d_min: float,
                     t_cap: float, level: float = 0.95) -> tuple[float, float]:
    """Profile-likelihood interval (lo, hi) of theta_k over all non-negative five-term models.

    The set of theta_k whose profile deviance lies within chi2(level, 1) of the global minimum
    ``d_min`` of the full fit ``full`` (5,); independent of which model the selection picked (an
    interval of the selected model alone would inherit the selection's optimism). ``t_cap`` is
    where the search for the upper limit starts (it grows by 4 until the profile exceeds the
    threshold).
    """
    limit = d_min + chi2_ppf(level, 1)
    t_hat = float(full[k])

    def excess(t: float) -> float:
        return _profile(a, avar, edf, k, t, full) - limit

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


def _dominant_range(k: int, theta: np.ndarray, tau_lo: float, tau_hi: float) -> tuple[float, float] | None:
    """Tau range (s) within [tau_lo, tau_hi] where term k is the largest model contribution."""
    grid = np.logspace(np.log10(tau_lo), np.log10(tau_hi), 400)
    parts = basis(grid) * theta
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
    a = basis(tau)
    full, _ = _irls(a, avar, edf, list(range(5)))
    d_min = deviance(a, avar, edf, full)
    intervals = []
    for k in range(5):
        # the smallest single-point 97.5 % bound: a start for the search of the upper limit
        cap = float(np.min(hi ** 2 / a[:, k]))
        intervals.append(profile_interval(a, avar, edf, k, full, d_min, cap))
    cols = _select(a, avar, edf, full)
    theta = np.where(np.isin(np.arange(5), cols), full, 0.0)
    w = edf / (2.0 * (a @ full) ** 2)
    chi2_red = float(np.sum(w * (avar - a @ full) ** 2) / max(len(tau) - len(cols), 1))
    terms: dict[str, NoiseTerm] = {}
    for k, name in enumerate(TERMS):
        lo, up = intervals[k]
        if k in cols:
            terms[name] = NoiseTerm(name, float(np.sqrt(full[k])), (float(np.sqrt(lo)), float(np.sqrt(up))), True,
                                    _dominant_range(k, theta, float(tau.min()), float(tau.max())))
        else:
            terms[name] = NoiseTerm(name, float("nan"), (0.0, float(np.sqrt(up))), False, None)
    return ChannelNoise(column, terms, theta, chi2_red, read_offs(tau, np.sqrt(avar)))


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

CALSET_NAMES = {
    "gyro": {"quantization": "quantization", "white": "arw", "bias_instability": "bias_instability", "rrw": "rrw",
             "rate_ramp": "rate_ramp"},
    "accel": {"quantization": "quantization", "white": "vrw", "bias_instability": "bias_instability", "rrw": "rrw",
              "rate_ramp": "rate_ramp"},
}


@dataclass(frozen=True)
class AllanAnalysis:
    """Allan analysis of one record: the OADEV curve with intervals and the noise terms per channel.

    ``quantity`` is ``"gyro"``, ``"accel"`` or None (units then the input's SI unit).
    """

    ci: DeviationCI
    fits: tuple[ChannelNoise, ...]
    quantity: str | None
    warnings: tuple[str, ...] = ()

    def noise_block(self) -> dict:
        """The calibration set's ``noise.<triad>`` block: per term a (3,) list (None = not observed)
        and ``<name>_ci95`` a (3,) list of [lo, hi] (for a term not observed, [0, upper bound])."""
        if self.quantity not in CALSET_NAMES or len(self.fits) != 3:
            raise ValueError("noise_block needs a gyro or accel triad (three channels)")
        block: dict = {}
        for term, name in CALSET_NAMES[self.quantity].items():
            block[name] = [t.value if t.observed else None for t in (f.terms[term] for f in self.fits)]
            block[name + "_ci95"] = [list(f.terms[term].ci95) for f in self.fits]
        return block


def analyze_record(y: np.ndarray, rate: float, columns: tuple[str, ...] | list[str], quantity: str | None = None,
                   taus: str | np.ndarray = "octave", gap_policy: str = "error", source: str = "data") -> AllanAnalysis:
    """OADEV with 95 % intervals and the IEEE 952 fit of rate samples ``y`` (N, C), SI, at ``rate`` Hz.

    ``quantity`` (``"gyro"`` | ``"accel"``) enables the unit plausibility check and names the
    calibration-set terms; ``taus`` and ``gap_policy`` as :func:`workbench.analysis.allan.deviation`
    (with gaps, noise identification uses the longest gap-free run).
    """
    from workbench.analysis import allan
    from workbench.analysis.allan_ci import confidence

    segments, warnings = allan.prepare_rate_data(y, tuple(columns), source, gap_policy, quantity)
    curve, x = allan.segment_deviation(segments, rate, "oadev", taus, tuple(columns), source)
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
