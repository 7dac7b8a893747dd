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
``gm``     sigma, u (steady-state std);  2 e2 (tau/2 - 3 p - p^2 tau/2 + 4 p^(tau/2+1) - p^(tau+1))
           T, s (correlation time)       / ((1 - p)^2 (1 - p^2) tau^2),  p = exp(-dt/T),
                                         e2 = sigma^2 (1 - p^2)
=========  ===========================  ==============================================

(WV formulas as documented for the R packages gmwm / wv; each is checked against the Allan
variance of simulated records in tests/analysis/test_gmwm.py.) Bias instability, a flicker
process, is approximated by a sum of Gauss-Markov (``gm``) terms, as the GMWM literature does;
its IEEE 952 value is read off the fitted Gauss-Markov sum as B = peak ADEV / 0.664 (its plateau).

Estimator: theta-hat = argmin (nu-hat - nu(theta))' Omega (nu-hat - nu(theta)), positive
parameters optimised in logs (scipy.optimize.least_squares, several starts). Two steps: first
Omega = diag of 1 / var(nu-hat_j) with var = 2 nu_j^2 / eta_j, eta_j = max(M_j / tau_j, 1)
(Percival & Walden 2000, eq. 313c); then the optimal Omega = V^-1, V the covariance of nu-hat
from a parametric bootstrap of the first-step model (its correlation shrunk toward the identity
by J / B, B records). The parameters' covariance is the asymptotic (D' V^-1 D)^-1, D = d nu / d u,
in u = (squared amplitudes, log correlation times): the WV is linear in the squares, so a term
the data cannot see (estimate at 0) keeps a finite upper limit. 95 % intervals: u +- 1.96 se
(squares clipped at 0, then the root); every derived term (N, Q, K, R, B) gets the 2.5-97.5 %
range of draws from that normal law.

Measured (tests/analysis/test_gmwm.py; white + Gauss-Markov + RRW, 2^17 samples, 10 seeds): rms
z of the errors against the reported standard errors 1.29 (N), 0.96 (GM sigma), 1.14 (GM time),
1.67 (RRW: on a short record its estimate is biased low and its uncertainty ~1.7x optimistic).
On a flicker bias instability (virtual IMU, 1 h) two Gauss-Markov terms give B within ~8 %,
and the RRW absorbs part of the flicker's long-tau tail (reported 2-4x the truth): prefer the
IEEE 952 fit's B and K there; GMWM's strength is a filter-ready Gauss-Markov model. Where the
bias instability barely shows in the record (hg1700, quasi-tactical, 1 h), B read off the
Gauss-Markov peak comes out 2-3x high (benchmarks/allan_gmwm_vs_ieee.py).

Public: :data:`PROCESSES`, :func:`parse_model`, :func:`wv_theory`, :func:`empirical_wv`,
:class:`GmwmFit`, :func:`fit_gmwm`, :func:`simulate`,
:func:`to_uncertainty_space`, :func:`from_uncertainty_space`, :func:`ieee_terms`.
References: Guerrier, Skaloud, Stebler, Victoria-Feser, "Wavelet-variance-based estimation for
composite stochastic processes", JASA 108 (2013); Stebler et al., "Generalized method of
wavelet moments for inertial navigation filter design", IEEE TAES 50 (2014); IEEE Std 952-1997.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from workbench.allan_model import FLICKER_AVAR
from workbench.errors import AnalysisError

PROCESSES = ("wn", "qn", "rw", "dr", "gm")
PARAMS = {"wn": ("white",), "qn": ("quantization",), "rw": ("rrw",), "dr": ("rate_ramp",), "gm": ("sigma", "tau_c")}
MIN_TERMS_PER_SCALE = 8  # a scale is used when its Allan average spans <= N / 8 samples: m <= N / 8
Z95 = 1.959963984540054


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


def wv_parts(kinds: tuple[str, ...], theta: np.ndarray, tau: np.ndarray, dt: float) -> np.ndarray:
    """Haar WV (P, J) of each process at scales ``tau`` (samples, even), parameters ``theta`` SI."""
    tau = np.asarray(tau, float)
    out, i = [], 0
    for k in kinds:
        if k == "gm":
            sigma, t_c = theta[i], theta[i + 1]
            p = np.exp(-dt / t_c)
            e2 = sigma ** 2 * (-np.expm1(-2.0 * dt / t_c))
            num = tau / 2 - 3 * p - p * p * tau / 2 + 4 * p ** (tau / 2 + 1) - p ** (tau + 1)
            out.append(2.0 * e2 * num / ((1 - p) ** 2 * (1 - p * p) * tau ** 2))
            i += 2
            continue
        v = theta[i]
        i += 1
        if k == "wn":
            out.append(v * v / dt / tau)
        elif k == "qn":
            out.append(6.0 * (v / dt) ** 2 / tau ** 2)
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
    (white u/sqrt(Hz), quantization u s, rrw u/sqrt(s), rate_ramp u/s, per Gauss-Markov term
    sigma u and tau_c s); ``se`` (P,) standard errors in the uncertainty space
    (:func:`to_uncertainty_space`: squared amplitudes, log correlation times); ``ci95`` (P, 2);
    ``terms``: IEEE 952 equivalents ``{name: (value, lo, hi)}`` (bias_instability from the
    Gauss-Markov sum); ``wv``/``wv_fit``/``tau`` (J,) empirical and fitted Haar WV at scales tau
    (samples); ``objective`` the final weighted distance; ``bootstrap`` records used for V.
    """

    column: str
    kinds: tuple[str, ...]
    theta: np.ndarray
    se: np.ndarray
    ci95: np.ndarray
    terms: dict[str, tuple[float, float, float]]
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
        """SI values: parameters with intervals, the IEEE 952 equivalents, the WV curves."""
        return {"column": self.column, "model": "+".join(self.kinds),
                "parameters": {n: {"value": float(v), "ci95": [float(a), float(b)]}
                               for n, v, (a, b) in zip(self.names(), self.theta, self.ci95)},
                "terms": {k: {"value": v, "ci95": [lo, hi]} for k, (v, lo, hi) in self.terms.items()},
                "tau_samples": self.tau.tolist(), "wv": self.wv.tolist(), "wv_fit": self.wv_fit.tolist(),
                "objective": self.objective, "bootstrap": self.bootstrap}


# -- simulation (parametric bootstrap, tests) ------------------------------------------------

def simulate(kinds: tuple[str, ...], theta: np.ndarray, n: int, dt: float, rng: np.random.Generator) -> np.ndarray:
    """A record (n,) of the composite model in u (each Gauss-Markov term started stationary)."""
    from scipy.signal import lfilter

    y = np.zeros(n)
    i = 0
    for k in kinds:
        if k == "gm":
            sigma, t_c = theta[i], theta[i + 1]
            p = np.exp(-dt / t_c)
            e = rng.standard_normal(n) * sigma * np.sqrt(-np.expm1(-2.0 * dt / t_c))
            e[0] = sigma * rng.standard_normal()
            y += lfilter([1.0], [1.0, -p], e)
            i += 2
            continue
        v = theta[i]
        i += 1
        if k == "wn":
            y += v / np.sqrt(dt) * rng.standard_normal(n)
        elif k == "qn":
            q = v * rng.standard_normal(n + 1)
            y += np.diff(q) / dt
        elif k == "rw":
            y += np.cumsum(v * np.sqrt(dt) * rng.standard_normal(n))
        else:
            y += v * dt * np.arange(n)
    return y


# -- the estimator -------------------------------------------------------------------------

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


def _fit(kinds, wv, tau, dt, whiten: np.ndarray, starts: list[np.ndarray]) -> tuple[np.ndarray, float]:
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
        res = least_squares(resid, p0, bounds=(lower, upper), method="trf", x_scale=1.0, max_nfev=4000,
                            xtol=1e-12, ftol=1e-12, gtol=1e-12)
        cost = float(2.0 * res.cost)
        if best is None or cost < best[1]:
            best = (res.x, cost)
    return best


def _time_bounds(tau: np.ndarray, dt: float) -> tuple[float, float]:
    """Bounds of log correlation time (s) the scales can resolve: dt / 50 to 1000 x the longest."""
    return float(np.log(dt / 50.0)), float(np.log(1e3 * tau[-1] * dt))


def _whitener(cov: np.ndarray) -> np.ndarray:
    """W with W' W = cov^-1 (inverse Cholesky factor)."""
    chol = np.linalg.cholesky(cov)
    return np.linalg.inv(chol)


def _bootstrap_cov(kinds, theta, n, dt, tau, b, rng, floor: np.ndarray) -> np.ndarray:
    """Covariance (J, J) of the empirical WV of ``b`` records simulated from the model, its
    correlation shrunk toward the identity by J / b, its variances at least ``floor`` (J,)."""
    sims = np.empty((b, len(tau)))
    rate = 1.0 / dt
    for i in range(b):
        wv, _ = empirical_wv(simulate(kinds, theta, n, dt, rng), rate)
        sims[i] = wv[: len(tau), 0]
    cov = np.cov(sims, rowvar=False)
    sd = np.sqrt(np.maximum(np.diag(cov), floor))
    corr = cov / np.outer(sd, sd)
    lam = min(1.0, len(tau) / b)
    corr = (1.0 - lam) * corr + lam * np.eye(len(tau))
    return corr * np.outer(sd, sd)


def _is_time(kinds: tuple[str, ...]) -> np.ndarray:
    """(P,) True where the parameter is a Gauss-Markov correlation time."""
    return np.array([k == "gm" and j == 1 for k in kinds for j in range(len(PARAMS[k]))])


def to_uncertainty_space(kinds: tuple[str, ...], theta: np.ndarray) -> np.ndarray:
    """Parameters in which the uncertainty is linearised: squares of the amplitudes (the WV is
    linear in them, so the information stays finite at 0) and logs of the correlation times."""
    t = _is_time(kinds)
    return np.where(t, np.log(theta), theta ** 2)


def from_uncertainty_space(kinds: tuple[str, ...], u: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_uncertainty_space` (negative squared amplitudes clipped at 0)."""
    t = _is_time(kinds)
    return np.where(t, np.exp(np.clip(np.where(t, u, 0.0), -700.0, 700.0)), np.sqrt(np.maximum(np.where(t, 0.0, u), 0.0)))


def _jacobian(kinds, u, tau, dt) -> np.ndarray:
    """d nu / d u (J, P) in the uncertainty space: exact for the squared amplitudes (the WV is
    linear in each: its part at amplitude 1), central differences for the log correlation times."""
    times = _is_time(kinds)
    theta = from_uncertainty_space(kinds, u)
    cols = []
    for i in range(len(u)):
        if times[i]:
            e = np.zeros(len(u))
            e[i] = 1e-5
            cols.append((wv_theory(kinds, from_uncertainty_space(kinds, u + e), tau, dt)
                         - wv_theory(kinds, from_uncertainty_space(kinds, u - e), tau, dt)) / 2e-5)
        else:
            unit = theta.copy()
            unit[i] = 1.0
            proc = int(np.searchsorted(np.cumsum([len(PARAMS[k]) for k in kinds]), i, side="right"))
            cols.append(wv_parts(kinds, unit, tau, dt)[proc])  # the part of parameter i's process
    return np.array(cols).T


def ieee_terms(kinds: tuple[str, ...], theta: np.ndarray, tau: np.ndarray, dt: float) -> dict[str, float]:
    """IEEE 952 equivalents (SI): the direct terms, and bias instability = the peak over the record's
    scales of the Gauss-Markov sum's ADEV / 0.664, the plateau a flicker floor leaves (NaN without
    Gauss-Markov terms)."""
    out = {"white": np.nan, "quantization": np.nan, "rrw": np.nan, "rate_ramp": np.nan, "bias_instability": np.nan}
    i = 0
    for k in kinds:
        if k == "gm":
            i += 2
            continue
        out[PARAMS[k][0]] = float(theta[i])
        i += 1
    if "gm" in kinds:
        gm_rows = [r for r, k in enumerate(kinds) if k == "gm"]
        fine = np.geomspace(tau[0], tau[-1], 200)
        fine = 2.0 * np.round(fine / 2.0)
        gm_wv = wv_parts(kinds, theta, fine, dt)[gm_rows].sum(axis=0)
        out["bias_instability"] = float(np.sqrt(2.0 * gm_wv.max() / FLICKER_AVAR))
    return out


def fit_gmwm(y: np.ndarray, rate: float, model: str = "wn+2gm+rw", column: str = "", bootstrap: int = 50,
             seed: int = 0, draws: int = 400) -> GmwmFit:
    """GMWM fit of ``model`` to one channel of rate samples ``y`` (N,) SI at ``rate`` Hz.

    ``bootstrap`` records simulated from the first-step fit estimate the optimal weighting
    matrix (0: keep the diagonal first-step weights); ``seed`` fixes them; ``draws`` samples of
    the asymptotic law give the intervals of the IEEE 952 equivalents.
    """
    kinds = parse_model(model)
    y = np.asarray(y, float).ravel()
    if not np.all(np.isfinite(y)):
        raise AnalysisError(f"{column or 'data'}: GMWM needs a gap-free record (NaN samples found)")
    dt = 1.0 / float(rate)
    wv, tau = empirical_wv(y, rate)
    wv = wv[:, 0]
    if len(tau) < _n_params(kinds) + 1:
        raise AnalysisError(f"{column or 'data'}: {len(tau)} wavelet scales cannot fit {_n_params(kinds)} "
                            f"parameters of {model!r} (a longer record or fewer terms)")
    eta = np.maximum((len(y) - tau + 1) / tau, 1.0)
    w0 = np.diag(1.0 / np.sqrt(2.0 * wv ** 2 / eta))
    p, cost = _fit(kinds, wv, tau, dt, w0, _starts(kinds, wv, tau, dt))
    cov = np.diag(2.0 * np.maximum(wv_theory(kinds, np.exp(p), tau, dt), 1e-300) ** 2 / eta)
    if bootstrap > 0:
        # variances floored at the chi-squared approximation from the empirical WV: a term the
        # first step sets to 0 must not make its own scales look exact (plug-in collapse)
        cov = _bootstrap_cov(kinds, np.exp(p), len(y), dt, tau, bootstrap, np.random.default_rng(seed),
                             2.0 * wv ** 2 / eta)
        p, cost = _fit(kinds, wv, tau, dt, _whitener(cov), [p, *_starts(kinds, wv, tau, dt)])
    theta = np.exp(p)
    u = to_uncertainty_space(kinds, theta)
    d = _jacobian(kinds, u, tau, dt)
    scale = np.linalg.norm(d, axis=0)
    scale[scale == 0] = 1.0  # columns of d span many decades: invert the information scaled
    ds = d / scale
    cov_u = np.linalg.pinv(ds.T @ np.linalg.solve(cov, ds)) / np.outer(scale, scale)
    se = np.sqrt(np.maximum(np.diag(cov_u), 0.0))
    ci_u = np.column_stack([u - Z95 * se, u + Z95 * se])
    ci = np.column_stack([from_uncertainty_space(kinds, ci_u[:, 0]), from_uncertainty_space(kinds, ci_u[:, 1])])
    sample = np.random.default_rng(seed + 1).multivariate_normal(u, (cov_u + cov_u.T) / 2, size=draws,
                                                                 method="eigh", check_valid="ignore")
    # correlation times drawn beyond what the scales resolve are held at the fit's bounds
    sample[:, _is_time(kinds)] = np.clip(sample[:, _is_time(kinds)], *_time_bounds(tau, dt))
    derived = [ieee_terms(kinds, from_uncertainty_space(kinds, s_), tau, dt) for s_ in sample]
    best = ieee_terms(kinds, theta, tau, dt)
    terms = {}
    for name, value in best.items():
        if np.isfinite(value):
            vals = np.array([dd[name] for dd in derived])
            terms[name] = (value, float(np.percentile(vals, 2.5)), float(np.percentile(vals, 97.5)))
    return GmwmFit(column, kinds, theta, se, ci, terms, tau, wv, wv_theory(kinds, theta, tau, dt), cost,
                   int(bootstrap), float(rate))
