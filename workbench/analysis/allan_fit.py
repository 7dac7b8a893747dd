"""IEEE Std 952 noise-term fit of an Allan variance curve, with model selection.

Model of the Allan variance of rate data (IEEE Std 952-1997 Annex C, table C.2):

    AVAR(tau) = 3 Q^2 / tau^2 + N^2 / tau + (2 ln2 / pi) B^2 + K^2 tau / 3 + R^2 tau^2 / 2

Q quantization (rad | m/s), N white noise density (ARW rad/s/sqrt(Hz) | VRW m/s^2/sqrt(Hz)),
B bias instability (rad/s | m/s^2), K rate random walk (rad/s^2/sqrt(Hz) | m/s^3/sqrt(Hz)),
R rate ramp (rad/s^2 | m/s^3). The model is linear in the squared coefficients theta, which
are fitted non-negatively (scipy NNLS) with weights 1 / var(AVAR_k), var = 2 model_k^2 / edf_k
(the chi-squared variance of each point, Greenhall EDF), re-weighted from the model until it
converges. Every subset of terms is fitted; subsets in which some term carries a third of
the model at fewer than two of the measured taus are rejected (the data do not show that term),
and among the rest the Bayesian information criterion on the weighted residuals picks one
(chi-squared divided by 2: neighbouring overlapping AVAR points are correlated, about half
of their information is shared); models within 2 of the best score are indistinguishable and
the one with fewest terms is taken. A fitted term whose removal raises that chi-squared by less
than 3.84 (95 %, 1 dof) gets a lower 95 % limit of 0: the data do not exclude its absence.
A term outside the chosen model is "not observed": its value is NaN and its 95 % interval is
[0, upper bound], the bound being the smallest ratio of a point's upper 97.5 % limit to the
term's basis function. For a fitted term the interval follows from the variance of theta
through a chi-squared law with edf = 2 theta^2 / var(theta); the variance is the least-squares
one (inflated by the reduced chi-squared when above 1) but at least what the single most
informative AVAR point gives alone (the points are correlated, so treating them as
independent would overstate the information).

Classic read-offs for comparison with datasheets and the thesis tables (1.1, 1.2, 2.1, 4.1):
N on the slope -1/2 line at tau = 1 s, K on the slope +1/2 line at tau = 3 s, B = min ADEV / 0.664.

Public: :data:`TERMS`, :class:`NoiseTerm`, :class:`ChannelNoise`, :func:`fit_channel`, :func:`fit_terms`,
:func:`read_offs`, :class:`AllanAnalysis`, :func:`analyze_record`, :func:`analyze_stream`.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import nnls
from scipy.stats import chi2

from workbench.analysis.allan_ci import DeviationCI

TERMS = ("quantization", "white", "bias_instability", "rrw", "rate_ramp")
FLICKER = 2.0 * np.log(2.0) / np.pi  # AVAR per B^2; ADEV floor 0.664 B
VISIBLE_SHARE = 1.0 / 3.0  # a term must carry this share of the model AVAR ...
VISIBLE_POINTS = 2  # ... at this many taus at least
PARSIMONY = 2.0  # BIC difference below which the model with fewer terms is preferred
CORRELATION = 2.0  # overlapping AVAR points at octave taus share about half their information:
# weighted chi-squared differences are divided by this before model comparison
_IRLS_ITER = 30


def basis(tau: np.ndarray) -> np.ndarray:
    """AVAR basis (K, 5) at taus (s): 3/tau^2, 1/tau, 2 ln2/pi, tau/3, tau^2/2."""
    tau = np.asarray(tau, float)
    return np.stack([3.0 / tau ** 2, 1.0 / tau, np.full_like(tau, FLICKER), tau / 3.0, tau ** 2 / 2.0], axis=1)


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


def _absence_allowed(a: np.ndarray, avar: np.ndarray, edf: np.ndarray, without: list[int], chi_best: float) -> bool:
    """Whether the model without a term fits within the 95 % chi-squared(1) margin of the best.

    The reduced model is refitted (non-negative, its coefficients free to reach zero); no term
    left at all means zero noise, which the data always exclude.
    """
    if not without:
        return False
    theta, w = _irls(a, avar, edf, without)
    chi = float(np.sum(w * (avar - a @ theta) ** 2)) / CORRELATION
    return chi - chi_best < chi2.ppf(0.95, 1)


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
    a = basis(tau)
    fits: dict[tuple[int, ...], tuple[np.ndarray, np.ndarray, float]] = {}
    for size in range(1, 6):
        for cols in itertools.combinations(range(5), size):
            theta, w = _irls(a, avar, edf, list(cols))
            model = a @ theta
            if np.any(theta[list(cols)] <= 0) or not np.all(model > 0):
                continue
            fits[cols] = (theta, w, float(np.sum(w * (avar - model) ** 2)) / CORRELATION)
    visible = {cols: f for cols, f in fits.items()
               if np.all(np.sum((a[:, list(cols)] * f[0][list(cols)]) / (a @ f[0])[:, None] >= VISIBLE_SHARE, axis=0)
                         >= VISIBLE_POINTS)}
    if not visible:
        raise ValueError(f"{column}: no noise model fits the Allan curve")
    score = {cols: f[2] + len(cols) * np.log(len(tau)) for cols, f in visible.items()}
    top = min(score.values())
    # models within 2 of the best score are not distinguishable: take the simplest of them
    best = min((c for c in score if score[c] <= top + PARSIMONY), key=lambda c: (len(c), score[c]))
    theta, w, chi_best = visible[best]
    cols = list(best)
    model = a @ theta
    dof = max(len(tau) - len(cols), 1)
    chi2_red = float(np.sum(w * (avar - model) ** 2) / dof)
    aw = a[:, cols] * np.sqrt(w)[:, None]
    cov = np.linalg.pinv(aw.T @ aw) * max(chi2_red, 1.0)
    terms: dict[str, NoiseTerm] = {}
    for k, name in enumerate(TERMS):
        if k in cols:
            # adjacent AVAR points are correlated, so the least-squares variance is optimistic:
            # never claim more than the single most informative point gives on its own
            var = max(cov[cols.index(k), cols.index(k)], float(np.min(1.0 / (w * a[:, k] ** 2))))
            nu = 2.0 * theta[k] ** 2 / var if var > 0 else np.inf
            lo, up = ((theta[k], theta[k]) if not np.isfinite(nu) else
                      (nu * theta[k] / chi2.ppf(0.975, nu), nu * theta[k] / chi2.ppf(0.025, nu)))
            if _absence_allowed(a, avar, edf, [c for c in best if c != k], chi_best):
                lo = 0.0  # the data do not exclude the term's absence at 95 %
            terms[name] = NoiseTerm(name, float(np.sqrt(theta[k])), (float(np.sqrt(lo)), float(np.sqrt(up))), True,
                                    _dominant_range(k, theta, float(tau.min()), float(tau.max())))
        else:
            bound = float(np.sqrt(np.min(hi ** 2 / a[:, k])))
            terms[name] = NoiseTerm(name, float("nan"), (0.0, bound), False, None)
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
    curve = allan.deviation(y, rate, "oadev", taus, columns, gap_policy, quantity, source)
    ci = confidence(curve, allan.phase(max(segments, key=len), rate))
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
