"""GMWM: a composite noise model fitted to the Haar wavelet variance (Guerrier et al. 2013).

The generalized method of wavelet moments fits a sum of independent processes to the Haar
wavelet variance (WV) nu^2_j of a rate record at the dyadic scales tau_j = 2^j samples,
j = 1..J. The Haar WV at scale tau_j is half the overlapping Allan variance at averaging
factor m = tau_j / 2 (the MODWT Haar wavelet coefficient is half the difference of two
adjacent means over m samples), so nu-hat comes from :func:`workbench.analysis.allan.deviation`
at octave factors. Processes (rate unit u: rad/s or m/s^2; dt the sample interval, s):

=========  ===========================  ==============================================
name       parameters (SI)              Haar WV at scale tau (samples)
=========  ===========================  ==============================================
``wn``     N, u/sqrt(Hz) (ARW / VRW)    s2 / tau,                  s2 = N^2 / dt
``qn``     Q, u s (angle / velocity)    6 q2 / tau^2,              q2 = (Q / dt)^2
``rw``     K, u/sqrt(s) (RRW)           g2 (tau^2 + 2) / (12 tau), g2 = K^2 dt
``dr``     R, u/s (rate ramp)           w^2 tau^2 / 16,            w = R dt
``fl``     B, u (bias instability)      B^2 x (the flicker ladder's WV), flat at FLICKER_AVAR B^2 / 2
``gm``     sigma, u (steady-state std);  2 sigma^2 [tau/2 (1 - p^2) - p (3 - 4 a + a^2)] / ((1 - p)^2 tau^2),
           T, s (correlation time)       p = exp(-dt/T), a = p^(tau/2) (:func:`gm_wv`, stable as T -> inf)
=========  ===========================  ==============================================

(WV formulas as documented for the R packages gmwm / wv; each is checked against the Allan
variance of simulated records in tests/analysis/test_gmwm.py.) Bias instability, a flicker
process, is a sum of Gauss-Markov processes either way: ``fl`` is a fixed ladder of them
(:func:`flicker_ladder`, three per decade, one amplitude B: the IEEE 952 term itself, and a
filter-ready Gauss-Markov bank), ``k*gm`` free terms as the GMWM literature does, B then read
off the fitted sum as peak ADEV / 0.664 (its plateau; 2-3x high where the floor barely shows).

Estimator: theta-hat = argmin (nu-hat - nu(theta))' Omega (nu-hat - nu(theta)). Two steps: first
Omega = diag of 1 / var(nu-hat_j) with var = 2 nu_j^2 / eta_j, eta_j = max(M_j / tau_j, 1)
(Percival & Walden 2000, eq. 313c); then the optimal Omega = V^-1, V the covariance of nu-hat
over B records simulated from the first-step model (:mod:`workbench.analysis.gmwm_sim`; the
correlation shrunk toward the identity by J / B). Without ``gm`` terms the WV is linear in the
squared amplitudes: non-negative least squares, a global optimum; with them, positive parameters
in logs (scipy.optimize.least_squares, several starts).

Intervals (95 %), from B further records simulated from the final model: for a linear model,
test inversion on each squared amplitude (:class:`_Inversion`: the set of values under which the
estimate lies within the 2.5-97.5 % range of the estimator's law, the other terms profiled);
a term whose interval reaches 0 is *not observed*: value NaN, interval [0, upper limit], never
tighter than the record's sensitivity. With ``gm`` terms: the basic bootstrap of refits on the
log (a term is not observed where the basic interval of its square reaches 0).

Measured (benchmarks/allan_gmwm_vs_ieee.py, tests/analysis/test_gmwm.py): see docs/allan.md
(GMWM). Cost: ~2 x B x 3 x 2 x 8192 simulated values whatever the record length; ~1 s per channel
at B = 100 on one core.

Public: :data:`PROCESSES`, :data:`MIN_BOOTSTRAP`, :func:`parse_model`, :func:`gm_wv`,
:func:`flicker_ladder`, :func:`wv_parts`, :func:`wv_theory`, :func:`empirical_wv`, :class:`GmwmFit`,
:func:`fit_gmwm`, :func:`simulate`, :func:`to_uncertainty_space`, :func:`ieee_terms`,
:func:`term_interval_text`.
References: Guerrier, Skaloud, Stebler, Victoria-Feser, "Wavelet-variance-based estimation for
composite stochastic processes", JASA 108 (2013); Stebler et al., "Generalized method of
wavelet moments for inertial navigation filter design", IEEE TAES 50 (2014); IEEE Std 952-1997.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from workbench.allan_model import FLICKER_AVAR
from workbench.errors import AnalysisError

PROCESSES = ("wn", "qn", "fl", "rw", "dr", "gm")
PARAMS = {"wn": ("white",), "qn": ("quantization",), "fl": ("bias_instability",), "rw": ("rrw",),
          "dr": ("rate_ramp",), "gm": ("sigma", "tau_c")}
LADDER_PER_DECADE = 3  # Gauss-Markov times of the flicker ladder per decade
LADDER_SPAN = (0.25, 1e10)  # its times, in samples
LADDER_FLAT = 2  # shortest Haar scale (samples) of the flat WV: the AVAR of one-sample averages
MIN_TERMS_PER_SCALE = 8  # a scale is used when its Allan average spans <= N / 8 samples: m <= N / 8
MIN_BOOTSTRAP = 50  # simulated records at least: with fewer the 2.5 % and 97.5 % quantiles (and V) come out narrow


def parse_model(text: str) -> tuple[str, ...]:
    """Processes of a model text such as ``"wn+2gm+rw"`` (``k*gm`` or ``kgm`` repeats a term), in the
    order of :data:`PROCESSES` (Gauss-Markov terms last)."""
    kinds: list[str] = []
    for token in (t.strip().lower() for t in text.split("+")):
        match = re.fullmatch(r"(\d+)\s*\*?\s*([a-z]+)", token) or re.fullmatch(r"()([a-z]+)", token)
        if not match or match.group(2) not in PROCESSES or (match.group(1) and int(match.group(1)) < 1):
            raise AnalysisError(f"GMWM model {text!r}: term {token!r} is not one of {', '.join(PROCESSES)} "
                                "(e.g. wn+2gm+rw)")
        count = int(match.group(1) or 1)
        if match.group(2) != "gm" and (count > 1 or match.group(2) in kinds):
            raise AnalysisError(f"GMWM model {text!r}: {match.group(2)} can appear once (only gm repeats)")
        kinds += [match.group(2)] * count
    return tuple(sorted(kinds, key=PROCESSES.index))


def _n_params(kinds: tuple[str, ...]) -> int:
    return sum(len(PARAMS[k]) for k in kinds)


_K = np.arange(25.0)
_FACT = np.cumprod(np.concatenate([[1.0], _K[1:]]))


def gm_wv(sigma: float, t_c: float, tau: np.ndarray, dt: float) -> np.ndarray:
    """Haar WV (J,) of a Gauss-Markov process (std ``sigma`` u, time ``t_c`` s) at scales ``tau``
    (samples, even): 2 sigma^2 [tau/2 (1 - p^2) - p (3 - 4 a + a^2)] / ((1 - p)^2 tau^2),
    p = exp(-dt / t_c), a = p^(tau/2); where u = tau dt / (2 t_c) < 0.5 the bracket, which
    cancels to O(u^3), is summed as its double series in x = dt / t_c and u (exact to ~1e-15)."""
    tau = np.asarray(tau, float)
    x = dt / t_c
    u = x * tau / 2.0
    p = np.exp(-x)
    closed = tau / 2.0 * -np.expm1(-2.0 * x) - p * (3.0 - 4.0 * np.exp(-u) + np.exp(-2.0 * u))
    k = _K[2:]
    first = (2.0 * (-x) ** k / _FACT[2:] * (2.0 ** k / (k + 1.0) - 1.0)).sum()
    us = np.minimum(u, 0.5)[..., None]
    n = _K[3:]
    series = first * us[..., 0] - p * ((-1.0) ** n * (2.0 ** n - 4.0) * us ** n / _FACT[3:]).sum(-1)
    num = np.where(u < 0.5, series, closed)
    return 2.0 * sigma ** 2 * num / (np.expm1(-x) ** 2 * tau ** 2)


@lru_cache(maxsize=8)
def flicker_ladder(dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The Gauss-Markov ladder of the ``fl`` process at sample period ``dt`` s: times (L,) s,
    :data:`LADDER_PER_DECADE` per decade over :data:`LADDER_SPAN` samples, and variances (L,) per
    B^2, non-negative least squares making the Haar WV FLICKER_AVAR / 2 (ADEV 0.664 B) at
    :data:`LADDER_FLAT` .. 2^27 samples (flat within +0.7/-1.0 %; modes of zero variance dropped):
    flat from one-sample averages on, as the virtual lab's :func:`workbench.sim.noise.flicker_design`
    (+0.3/-0.6 %)."""
    from scipy.optimize import nnls

    lo, hi = (np.log10(v) for v in LADDER_SPAN)
    times = dt * 10.0 ** np.arange(lo, hi + 1e-9, 1.0 / LADDER_PER_DECADE)
    tau = 2.0 ** np.arange(np.log2(LADDER_FLAT), 28)
    basis = np.array([gm_wv(1.0, t, tau, dt) for t in times]).T / (FLICKER_AVAR / 2.0)
    var, _ = nnls(basis, np.ones(len(tau)))
    keep = var > 0
    times, var = times[keep], var[keep]
    times.setflags(write=False)
    var.setflags(write=False)
    return times, var


def wv_parts(kinds: tuple[str, ...], theta: np.ndarray, tau: np.ndarray, dt: float) -> np.ndarray:
    """Haar WV (P, J) of each process at scales ``tau`` (samples, even), parameters ``theta`` SI."""
    tau = np.asarray(tau, float)
    out, i = [], 0
    for k in kinds:
        if k == "gm":
            out.append(gm_wv(theta[i], theta[i + 1], tau, dt))
            i += 2
            continue
        v = theta[i]
        i += 1
        if k == "wn":
            out.append(v * v / dt / tau)
        elif k == "qn":
            out.append(6.0 * (v / dt) ** 2 / tau ** 2)
        elif k == "fl":
            times, var = flicker_ladder(float(dt))
            out.append(v * v * sum(gm_wv(np.sqrt(g), t, tau, dt) for t, g in zip(times, var)))
        elif k == "rw":
            out.append(v * v * dt * (tau ** 2 + 2.0) / (12.0 * tau))
        else:  # dr
            out.append((v * dt) ** 2 * tau ** 2 / 16.0)
    return np.array(out)


def wv_theory(kinds: tuple[str, ...], theta: np.ndarray, tau: np.ndarray, dt: float) -> np.ndarray:
    """Haar WV (J,) of the composite model (sum of :func:`wv_parts`), in u^2."""
    return wv_parts(kinds, theta, tau, dt).sum(axis=0)


def empirical_wv(y: np.ndarray, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Haar WV (J, C) of rate samples ``y`` (N, C) SI at dyadic scales, and the scales tau_j (J,)
    in samples: nu^2 = OADEV(m)^2 / 2 at m = tau / 2 <= N / :data:`MIN_TERMS_PER_SCALE`."""
    from workbench.analysis.allan import deviation

    y = np.asarray(y, float)
    y = y[:, None] if y.ndim == 1 else y
    top = int(np.floor(np.log2(len(y) / MIN_TERMS_PER_SCALE)))
    if top < 2:
        raise AnalysisError(f"GMWM needs at least {4 * MIN_TERMS_PER_SCALE} samples, got {len(y)}")
    m = 2.0 ** np.arange(top + 1)
    curve = deviation(y, rate, "oadev", m / rate)
    return curve.dev ** 2 / 2.0, 2.0 * curve.m.astype(float)


@dataclass(frozen=True)
class GmwmFit:
    """A GMWM fit of one channel (SI of the input rate unit u).

    ``kinds`` the processes; ``theta`` (P,) their parameters in the order of :data:`PARAMS`
    (white u/sqrt(Hz), quantization u s, bias_instability u, rrw u/sqrt(s), rate_ramp u/s, per
    Gauss-Markov term sigma u and tau_c s); ``se`` (P,) bootstrap standard deviations in the
    uncertainty space (:func:`to_uncertainty_space`: squared amplitudes, log correlation times);
    ``ci95`` (P, 2); ``terms``: IEEE 952 equivalents ``{name: (value, lo, hi)}``, value NaN and
    interval [0, upper limit] where ``resolved[name]`` is False (the term is not observed);
    ``wv``/``wv_fit``/``tau`` (J,) empirical and fitted Haar WV at scales tau (samples);
    ``objective`` the final weighted distance; ``bootstrap`` records per bootstrap set.
    """

    column: str
    kinds: tuple[str, ...]
    theta: np.ndarray
    se: np.ndarray
    ci95: np.ndarray
    terms: dict[str, tuple[float, float, float]]
    resolved: dict[str, bool]
    tau: np.ndarray
    wv: np.ndarray
    wv_fit: np.ndarray
    objective: float
    bootstrap: int
    rate: float

    def names(self) -> list[str]:
        """Parameter names, ``gm1_sigma``, ``gm1_tau_c``, ... for the Gauss-Markov terms."""
        out, g = [], 0
        for k in self.kinds:
            if k == "gm":
                g += 1
                out += [f"gm{g}_sigma", f"gm{g}_tau_c"]
            else:
                out.append(PARAMS[k][0])
        return out

    def to_dict(self) -> dict:
        """SI values: parameters with intervals, the IEEE 952 equivalents (value None where not
        observed), the WV curves."""
        return {"column": self.column, "model": "+".join(self.kinds),
                "parameters": {n: {"value": float(v), "ci95": [float(a), float(b)]}
                               for n, v, (a, b) in zip(self.names(), self.theta, self.ci95)},
                "terms": {k: {"value": v if self.resolved[k] else None, "observed": self.resolved[k], "ci95": [lo, hi]}
                          for k, (v, lo, hi) in self.terms.items()},
                "tau_samples": self.tau.tolist(), "wv": self.wv.tolist(), "wv_fit": self.wv_fit.tolist(),
                "objective": self.objective, "bootstrap": self.bootstrap}


# -- simulation (tests; the bootstrap draws its WV through workbench.analysis.gmwm_sim) -------

def simulate(kinds: tuple[str, ...], theta: np.ndarray, n: int, dt: float, rng: np.random.Generator) -> np.ndarray:
    """A record (n,) of the composite model in u, sample by sample (each Gauss-Markov term, and
    each mode of the flicker ladder, started stationary)."""
    from scipy.signal import lfilter

    def gauss_markov(sigma, t_c):
        p = np.exp(-dt / t_c)
        e = rng.standard_normal(n) * sigma * np.sqrt(-np.expm1(-2.0 * dt / t_c))
        e[0] = sigma * rng.standard_normal()
        return lfilter([1.0], [1.0, -p], e)

    y = np.zeros(n)
    i = 0
    for k in kinds:
        if k == "gm":
            y += gauss_markov(theta[i], theta[i + 1])
            i += 2
            continue
        v = theta[i]
        i += 1
        if k == "wn":
            y += v / np.sqrt(dt) * rng.standard_normal(n)
        elif k == "qn":
            q = v * rng.standard_normal(n + 1)
            y += np.diff(q) / dt
        elif k == "fl":
            for t_c, var in zip(*flicker_ladder(float(dt))):
                y += gauss_markov(v * np.sqrt(var), t_c)
        elif k == "rw":
            y += np.cumsum(v * np.sqrt(dt) * rng.standard_normal(n))
        else:
            y += v * dt * np.arange(n)
    return y


# -- the estimator -------------------------------------------------------------------------

def _is_linear(kinds: tuple[str, ...]) -> bool:
    """Without Gauss-Markov terms the WV is linear in the squared amplitudes."""
    return "gm" not in kinds


def _starts(kinds: tuple[str, ...], wv: np.ndarray, tau: np.ndarray, dt: float) -> list[np.ndarray]:
    """Starting log-parameters: levels read off the WV, Gauss-Markov times spread over the scales."""
    n_gm = kinds.count("gm")
    level = np.sqrt(2.0 * wv)  # ADEV at m = tau / 2
    t_s = tau / 2 * dt
    starts = []
    for shift in (0.0, -1.0, 1.0):
        if n_gm:
            centres = np.linspace(np.log(t_s[0]) + 1.0, np.log(t_s[-1]) - 1.0, n_gm + 2)[1:-1] + shift
        p = []
        g = 0
        for k in kinds:
            if k == "wn":
                p.append(np.log(level[0] * np.sqrt(t_s[0])))
            elif k == "qn":
                p.append(np.log(0.1 * level[0] * t_s[0]))
            elif k == "fl":
                p.append(np.log(level.min() / np.sqrt(FLICKER_AVAR) * 0.5))
            elif k == "rw":
                p.append(np.log(level[-1] / np.sqrt(t_s[-1]) * 0.3))
            elif k == "dr":
                p.append(np.log(0.1 * level[-1] / t_s[-1]))
            else:
                t_c = np.exp(centres[g])
                j = int(np.argmin(np.abs(np.log(t_s) - np.log(t_c))))
                p += [np.log(level[j] + 1e-300), np.log(t_c)]
                g += 1
        starts.append(np.array(p))
    return starts


def _fit(kinds, wv, tau, dt, whiten: np.ndarray, starts: list[np.ndarray], max_nfev: int = 4000
         ) -> tuple[np.ndarray, float]:
    """Minimise |whiten @ (wv - nu(exp p))|^2 over log-parameters p from each start; (p, objective)."""
    from scipy.optimize import least_squares

    lo_t, hi_t = _time_bounds(tau, dt)

    def resid(p):
        return whiten @ (wv - wv_theory(kinds, np.exp(p), tau, dt))

    best = None
    lower, upper = [], []
    for k in kinds:
        if k == "gm":
            lower += [-np.inf, lo_t]
            upper += [np.inf, hi_t]
        else:
            lower.append(-np.inf)
            upper.append(np.inf)
    for p0 in starts:
        p0 = np.clip(p0, np.array(lower) + 1e-9, np.array(upper) - 1e-9)
        res = least_squares(resid, p0, bounds=(lower, upper), method="trf", x_scale=1.0, max_nfev=max_nfev,
                            xtol=1e-12, ftol=1e-12, gtol=1e-12)
        cost = float(2.0 * res.cost)
        if best is None or cost < best[1]:
            best = (res.x, cost)
    return best


def _linear_fit(basis: np.ndarray, wv: np.ndarray, whiten: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Weighted least squares of ``wv`` (J,) or (J, R) on the WV ``basis`` (J, P) of the squared
    amplitudes: (non-negative solution (P,) or (P, R), unconstrained solution, objective of the first)."""
    from scipy.optimize import nnls

    a = whiten @ basis
    scale = np.linalg.norm(a, axis=0)
    scale[scale == 0] = 1.0
    a = a / scale
    b = whiten @ wv
    free = np.linalg.lstsq(a, b, rcond=None)[0] / (scale[:, None] if b.ndim == 2 else scale)
    cols = b if b.ndim == 2 else b[:, None]
    pos = np.array([nnls(a, c)[0] for c in cols.T]).T / scale[:, None]
    pos = pos if b.ndim == 2 else pos[:, 0]
    r = (whiten @ (wv - basis @ pos))
    return pos, free, float(np.sum(r ** 2))


def _time_bounds(tau: np.ndarray, dt: float) -> tuple[float, float]:
    """Bounds of log correlation time (s) the scales can resolve: dt / 50 to 1000 x the longest."""
    return float(np.log(dt / 50.0)), float(np.log(1e3 * tau[-1] * dt))


def _whitener(cov: np.ndarray) -> np.ndarray:
    """W with W' W = cov^-1 (inverse Cholesky factor)."""
    chol = np.linalg.cholesky(cov)
    return np.linalg.inv(chol)


def _shrunk_cov(sims: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """Covariance (J, J) of simulated WV (B, J), its correlation shrunk toward the identity by
    J / B, its variances at least ``floor`` (J,)."""
    b, j = sims.shape
    cov = np.cov(sims, rowvar=False)
    sd = np.sqrt(np.maximum(np.diag(cov), floor))
    corr = cov / np.outer(sd, sd)
    lam = min(1.0, j / b)
    corr = (1.0 - lam) * corr + lam * np.eye(j)
    return corr * np.outer(sd, sd)


def _is_time(kinds: tuple[str, ...]) -> np.ndarray:
    """(P,) True where the parameter is a Gauss-Markov correlation time."""
    return np.array([k == "gm" and j == 1 for k in kinds for j in range(len(PARAMS[k]))])


def to_uncertainty_space(kinds: tuple[str, ...], theta: np.ndarray) -> np.ndarray:
    """Parameters in which the uncertainty is expressed: squares of the amplitudes (the WV is
    linear in them, so a term at 0 keeps a finite spread) and logs of the correlation times."""
    t = _is_time(kinds)
    return np.where(t, np.log(np.where(t, theta, 1.0)), theta ** 2)


def ieee_terms(kinds: tuple[str, ...], theta: np.ndarray, tau: np.ndarray, dt: float) -> dict[str, float]:
    """IEEE 952 equivalents (SI): the direct terms (``fl`` gives bias instability itself), else
    bias instability = the peak over the record's scales of the Gauss-Markov sum's ADEV / 0.664,
    the plateau a flicker floor leaves (NaN without either)."""
    out = {"white": np.nan, "quantization": np.nan, "bias_instability": np.nan, "rrw": np.nan, "rate_ramp": np.nan}
    i = 0
    for k in kinds:
        if k == "gm":
            i += 2
            continue
        out[PARAMS[k][0]] = float(theta[i])
        i += 1
    if "gm" in kinds and "fl" not in kinds:
        gm_rows = [r for r, k in enumerate(kinds) if k == "gm"]
        fine = np.geomspace(tau[0], tau[-1], 200)
        fine = 2.0 * np.round(fine / 2.0)
        gm_wv_sum = wv_parts(kinds, theta, fine, dt)[gm_rows].sum(axis=0)
        out["bias_instability"] = float(np.sqrt(2.0 * gm_wv_sum.max() / FLICKER_AVAR))
    return out


def _basic_interval(est: float, refits: np.ndarray, log_only: bool) -> tuple[bool, float, float]:
    """(resolved, lo, hi) of a squared amplitude (or, ``log_only``, a positive parameter) of a
    Gauss-Markov model from its bootstrap refits: the basic bootstrap on the log where the lower
    limit of the basic interval on the squares is above 0, else [0, 2 est - 2.5 % quantile]."""
    q_lo, q_hi = np.quantile(refits, [0.025, 0.975])
    if log_only or (2.0 * est - q_hi > 0 and q_lo > 0):
        return True, est * est / q_hi, est * est / q_lo
    return False, 0.0, max(2.0 * est - q_lo, q_hi)


class _Inversion:
    """Test-inversion intervals of the squared amplitudes of a linear model (no Gauss-Markov term).

    The pivot is the unconstrained weighted least-squares estimate x_i = H_i nu-hat, H = (W A)^+ W.
    For a candidate value v of x_i the model is profiled (x_i = v, the other terms the
    non-negative fit of nu-hat - v A_i) and the law of x_i under it is read off the bootstrap WV
    deviations, each scale's scaled by the ratio of the profiled model's WV to the simulated
    model's (the WV at a scale keeps its shape of law, scaled chi-squared, as its level moves).
    The 95 % interval is {v : x_i-hat lies between the 2.5 and 97.5 % quantiles under v}; when
    it reaches 0 the term is not observed and only its upper limit is reported (at least the
    limit of a record without the term, as a power-constrained limit).
    """

    def __init__(self, basis: np.ndarray, whiten: np.ndarray, wv: np.ndarray, dev: np.ndarray, centre: np.ndarray):
        self.basis, self.whiten, self.wv, self.dev, self.centre = basis, whiten, wv, dev, centre
        self.h = np.linalg.pinv(whiten @ basis) @ whiten
        self.free = self.h @ wv

    def _profile(self, i: int, v: float) -> np.ndarray:
        others = [j for j in range(self.basis.shape[1]) if j != i]
        x = np.empty(self.basis.shape[1])
        x[i] = v
        if others:
            x[others] = _linear_fit(self.basis[:, others], self.wv - v * self.basis[:, i], self.whiten)[0]
        return x

    def refits(self, i: int, v: float) -> np.ndarray:
        """(B,) unconstrained estimates of x_i on the bootstrap WV scaled to the model profiled at v."""
        nu = self.basis @ self._profile(i, v)
        return (nu + self.dev * (nu / self.centre)) @ self.h[i]

    def interval(self, i: int) -> tuple[bool, float, float]:
        """(resolved, lo, hi) of x_i (squared amplitude, SI^2)."""
        obs = float(self.free[i])
        q = lambda v, p: float(np.quantile(self.refits(i, v), p))  # noqa: E731
        spread = max(q(max(obs, 0.0), 0.975) - q(max(obs, 0.0), 0.025), 1e-300)
        # upper limit: x_i-hat at the 2.5 % quantile; an estimate below the median of a record
        # without the term gives the limit of that median (never tighter than the record's
        # sensitivity: a downward fluctuation must not exclude what the data cannot see)
        target = max(obs, q(0.0, 0.5))
        lo_v, hi_v = max(obs, 0.0), max(obs, 0.0) + spread
        while q(hi_v, 0.025) < target:
            lo_v, hi_v = hi_v, 2.0 * hi_v
        upper = _bisect(lambda v: q(v, 0.025) - target, lo_v, hi_v)
        if q(0.0, 0.975) >= obs:
            return False, 0.0, upper
        return True, _bisect(lambda v: q(v, 0.975) - obs, 0.0, max(obs, 0.0) + spread), upper


def _bisect(f, lo: float, hi: float, iters: int = 40) -> float:
    """Root of an increasing ``f`` in [lo, hi] (relative precision ~1e-6 of the bracket)."""
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        if f(mid) < 0:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-7 * hi:
            break
    return 0.5 * (lo + hi)


def fit_gmwm(y: np.ndarray, rate: float, model: str = "wn+fl+rw", column: str = "", bootstrap: int = 100,
             seed: int = 0) -> GmwmFit:
    """GMWM fit of ``model`` to one channel of rate samples ``y`` (N,) SI at ``rate`` Hz.

    Two steps: diagonal weights, then the inverse covariance of the WV of ``bootstrap`` records
    simulated from the first-step model (:func:`workbench.analysis.gmwm_sim.wv_draws`). As many
    records simulated from the final model give the intervals: test inversion (:class:`_Inversion`) for a model without
    Gauss-Markov terms, else the basic bootstrap of refits (:func:`_basic_interval`). ``seed``
    fixes the simulations.
    """
    from workbench.analysis.gmwm_sim import wv_draws

    kinds = parse_model(model)
    y = np.asarray(y, float).ravel()
    if not np.all(np.isfinite(y)):
        raise AnalysisError(f"{column or 'data'}: GMWM needs a gap-free record (NaN samples found)")
    if bootstrap < MIN_BOOTSTRAP:
        raise AnalysisError(f"{column or 'data'}: GMWM needs at least {MIN_BOOTSTRAP} bootstrap records, "
                            f"got {bootstrap}")
    dt = 1.0 / float(rate)
    wv, tau = empirical_wv(y, rate)
    wv = wv[:, 0]
    if len(tau) < _n_params(kinds) + 1:
        raise AnalysisError(f"{column or 'data'}: {len(tau)} wavelet scales cannot fit {_n_params(kinds)} "
                            f"parameters of {model!r} (a longer record or fewer terms)")
    linear = _is_linear(kinds)
    basis = wv_parts(kinds, np.ones(_n_params(kinds)), tau, dt).T if linear else None

    def estimate(target, whiten, starts, max_nfev=4000):
        if linear:
            pos, _, cost = _linear_fit(basis, target, whiten)
            return np.sqrt(pos), cost
        p, cost = _fit(kinds, target, tau, dt, whiten, starts, max_nfev)
        return np.exp(p), cost

    eta = np.maximum((len(y) - tau + 1) / tau, 1.0)
    theta1, _ = estimate(wv, np.diag(1.0 / np.sqrt(2.0 * wv ** 2 / eta)), _starts(kinds, wv, tau, dt))
    rng = np.random.default_rng(seed)
    centre = np.maximum(wv_theory(kinds, theta1, tau, dt), 1e-300)
    sims = wv_draws(kinds, theta1, len(y), dt, tau, bootstrap, rng, flicker_ladder(dt), centre)
    # variances floored at a third of the chi-squared approximation from the empirical WV (eta is
    # ~3x conservative for white noise): a term the first step sets to 0 must not make its own
    # scales look exact (plug-in collapse)
    whiten = _whitener(_shrunk_cov(sims, 2.0 * wv ** 2 / eta / 3.0))
    theta, cost = estimate(wv, whiten, [np.log(np.maximum(theta1, 1e-300)), *_starts(kinds, wv, tau, dt)])
    fitted = wv_theory(kinds, theta, tau, dt)
    # the intervals from a second, independent set: the spread of an estimator weighted by V,
    # read on the very records V came from, is optimistic (~(1 - J / B) in variance)
    centre = np.maximum(fitted, 1e-300)
    dev = wv_draws(kinds, theta, len(y), dt, tau, bootstrap, rng, flicker_ladder(dt), centre) - centre
    times = _is_time(kinds)
    u = to_uncertainty_space(kinds, theta)
    best = ieee_terms(kinds, theta, tau, dt)
    ci = np.empty((len(theta), 2))
    terms, resolved = {}, {}
    if linear:
        inv = _Inversion(basis, whiten, wv, dev, centre)
        se = np.std(np.array([inv.refits(i, u[i]) for i in range(len(u))]), axis=1, ddof=1)
        for i, k in enumerate(kinds):
            ok, lo, hi = inv.interval(i)
            ci[i] = np.sqrt(lo), np.sqrt(hi)
            resolved[PARAMS[k][0]] = ok
            terms[PARAMS[k][0]] = (float(theta[i]) if ok else float("nan"), float(ci[i, 0]), float(ci[i, 1]))
    else:
        draws = np.maximum(fitted + dev * (fitted / centre), 0.0)
        refits = np.array([estimate(d, whiten, [np.log(theta)], 200)[0] for d in draws])
        u_r = np.array([to_uncertainty_space(kinds, r) for r in refits])
        se = np.std(u_r, axis=0, ddof=1)
        for i in range(len(theta)):
            if times[i]:
                ci[i] = _basic_interval(theta[i], refits[:, i], True)[1:]
            else:
                ci[i] = np.sqrt(_basic_interval(u[i], u_r[:, i], False)[1:])
        derived = [ieee_terms(kinds, r, tau, dt) for r in refits]
        for name, value in best.items():
            if np.isfinite(value):
                ok, lo, hi = _basic_interval(value ** 2, np.array([d[name] for d in derived]) ** 2, False)
                resolved[name] = ok
                terms[name] = (value if ok else float("nan"), float(np.sqrt(lo)), float(np.sqrt(hi)))
    return GmwmFit(column, kinds, theta, se, ci, terms, resolved, tau, wv, fitted, cost, int(bootstrap), float(rate))


def term_interval_text(quantity: str | None, name: str, value: float, lo: float, hi: float, resolved: bool) -> str:
    """``term value [lo .. hi]`` in lab units, or ``term not observed (< hi)`` for a term the
    record does not resolve (:class:`GmwmFit`)."""
    from workbench.analysis.allan_terms import TERM_LABELS, term_text

    upper = term_text(quantity, name, hi).split(" ", 1)[1]
    if not resolved:
        return f"{TERM_LABELS[name]} not observed (< {upper})"
    return f"{term_text(quantity, name, value)} [{term_text(quantity, name, lo).split(' ', 1)[1]} .. {upper}]"
