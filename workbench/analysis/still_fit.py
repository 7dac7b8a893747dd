"""Accelerometer and gyro from the still stretches of ``free`` steps (a unit set down by hand, no table).

The stationarity detector (:mod:`workbench.analysis.stationarity`) finds the still stretches of
every ``free`` step; each gives one position: the mean specific force and rate (``settle_s``
dropped at both ends). No orientation is known, so:

- :func:`fit_accel_norm`: the accelerometer from the norm of gravity alone (the multi-position
  fit without known orientations): ``|inv(I + M) (f - b)| = g`` at every position, ``g`` the
  site's normal gravity. Nine parameters (bias, symmetric ``M``: scale factors and the symmetric
  part of the misalignment; its antisymmetric part is a rotation no norm sees) need at least 10
  positions; 6-9 positions give bias and scale factors only (``M`` diagonal); fewer are refused.
- :func:`fit_gyro_bias`: the mean rate over the stretches, minus the Earth rate's vertical part
  (along the measured down direction, ``-Omega_e sin(lat)``); its horizontal part
  (``Omega_e cos(lat)``, heading unknown) goes into the variance. The sigma is the larger of the
  sigma of the mean (white noise, scaled by the samples' own correlation time, :mod:`effective_n`) and the
  scatter of the stretch means (when there are several), with the g-sensitivity ``G`` (rate per
  specific force) in quadrature: no ``G`` is fitted (the stretches' orientations are unknown, and
  one orientation cannot separate ``G f`` from the bias), so the mean rate holds ``b + G f_mean``
  and the bias valid in any orientation is uncertain by ``sigma_G |f_mean|`` per axis, ``sigma_G``
  the grade's g-sensitivity spread or, for a board of unknown grade, :data:`G_SENSITIVITY_BOUND`.

Both return :class:`workbench.analysis.turntable.TriadFit` (residual table per stretch), so the
multi-position procedure reports them as it does its table fits.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from workbench.analysis import stationarity
from workbench.analysis.effective_n import tau_int
from workbench.analysis.turntable import TriadFit
from workbench.earth import EARTH_RATE
from workbench.units import G0, from_unit, to_unit
from workbench.errors import AnalysisError
from workbench.session import Session

_NAN3 = np.full(3, np.nan)
MIN_FULL, MIN_DIAG = 10, 6  # positions for the 9- and the 6-parameter norm fit
MAX_BIAS_SIGMA, MAX_SCALE_SIGMA = 0.5, 0.05  # m/s^2 and dimensionless: beyond, the positions do not observe the fit
# rad/s per m/s^2, 1-sigma g-sensitivity of a gyro of unknown grade: a consumer MEMS gyro's "linear acceleration
# sensitivity" (MPU-6000/6050 product specification rev. 3.4, table 6.1: 0.1 °/s/g, the ITG-3200 class alike)
G_SENSITIVITY_BOUND = float(from_unit(0.1, "deg/s/g"))


@dataclass(frozen=True)
class StillMean:
    """One still stretch: ``step``, ``t0``/``t1`` s, ``n`` samples, mean ``accel`` m/s^2 and ``gyro`` rad/s
    (3,), and their per-sample standard deviations ``accel_std``, ``gyro_std`` (3,), body frame;
    ``accel_tau``, ``gyro_tau`` (3,) the integrated autocorrelation time of the samples (1 = white;
    :mod:`workbench.analysis.effective_n`): the mean's sigma is ``std * sqrt(tau / n)``."""

    step: int
    t0: float
    t1: float
    n: int
    accel: np.ndarray
    gyro: np.ndarray
    accel_std: np.ndarray
    gyro_std: np.ndarray
    accel_tau: np.ndarray = field(default_factory=lambda: np.ones(3))
    gyro_tau: np.ndarray = field(default_factory=lambda: np.ones(3))

    @property
    def accel_sigma(self) -> np.ndarray:
        """(3,) m/s^2, sigma of the mean specific force (correlation within the stretch included)."""
        return self.accel_std * np.sqrt(self.accel_tau / self.n)

    @property
    def gyro_sigma(self) -> np.ndarray:
        """(3,) rad/s, sigma of the mean rate (correlation within the stretch included)."""
        return self.gyro_std * np.sqrt(self.gyro_tau / self.n)


def still_means(session: Session, settle_s: float = 0.25) -> list[StillMean]:
    """The still stretches of every ``free`` step as :class:`StillMean` (``settle_s`` s dropped at each end)."""
    out = []
    fs = session.sample_rate_hz
    cut = int(round(settle_s * fs))
    for st in session.steps_of_kind("free"):
        df = session.step_samples(st.index)
        if len(df) < fs:
            continue
        g = df[["gx", "gy", "gz"]].to_numpy(float)
        a = df[["ax", "ay", "az"]].to_numpy(float)
        t = df["t"].to_numpy(float)
        ok = session.good("gyro", st.index) & session.good("accel", st.index)
        found = stationarity.detect(g, a, fs)
        for s0, s1 in found.stretches:
            sel = np.arange(s0 + cut, s1 - cut)
            sel = sel[ok[sel]]
            if len(sel) < 10:
                continue
            out.append(StillMean(st.index, float(t[sel[0]]), float(t[sel[-1]]), len(sel), a[sel].mean(axis=0),
                                 g[sel].mean(axis=0), a[sel].std(axis=0, ddof=1), g[sel].std(axis=0, ddof=1),
                                 tau_int(a[sel], pooled=False), tau_int(g[sel], pooled=False)))
    return out


def _residual_table(means: list[StillMean], ref: np.ndarray, before: np.ndarray, after: np.ndarray,
                    sigma: np.ndarray, norm_before: np.ndarray, norm_after: np.ndarray) -> pd.DataFrame:
    rows = []
    for i, m in enumerate(means):
        row = {"step": m.step, "label": f"still {m.t0:.1f}-{m.t1:.1f} s", "used": True}
        for j, ax in enumerate("xyz"):
            row.update({f"ref_{ax}": ref[i, j], f"before_{ax}": before[i, j], f"after_{ax}": after[i, j],
                        f"sigma_{ax}": sigma[i, j]})
        row.update({"before_norm": norm_before[i], "after_norm": norm_after[i]})
        rows.append(row)
    return pd.DataFrame(rows)


def _sym(p6: np.ndarray) -> np.ndarray:
    m = np.diag(p6[:3])
    m[0, 1] = m[1, 0] = p6[3]
    m[0, 2] = m[2, 0] = p6[4]
    m[1, 2] = m[2, 1] = p6[5]
    return m


def fit_accel_norm(means: list[StillMean], gravity: float) -> TriadFit:
    """Accelerometer bias and (symmetric) ``M`` from the gravity norm at the still positions (module docstring).

    ``gravity`` m/s^2 the local magnitude. Sigmas: ``s^2 inv(J^T J)`` with ``s`` the larger of the
    residual RMS and the white-noise sigma of a position mean (so a perfect fit is not overtrusted).
    """
    k = len(means)
    if k < MIN_DIAG:
        raise AnalysisError(f"accelerometer norm fit: {k} still stretch(es); at least {MIN_DIAG} orientations are "
                            "needed (set the unit down in 6 or more different orientations)")
    f = np.array([m.accel for m in means])
    full = k >= MIN_FULL
    n_par = 9 if full else 6

    def unpack(p):
        mm = _sym(p[3:]) if full else np.diag(p[3:6])
        return p[:3], mm

    def resid(p):
        b, mm = unpack(p)
        return np.linalg.norm(np.linalg.solve(np.eye(3) + mm, (f - b).T).T, axis=1) - gravity

    sol = least_squares(resid, np.zeros(n_par), method="lm", x_scale="jac")
    r = sol.fun
    noise = float(np.mean([np.linalg.norm(m.accel_sigma) / np.sqrt(3) for m in means]))
    dof = k - n_par
    s2 = max(float(r @ r) / dof if dof > 0 else 0.0, noise**2)
    cov = s2 * np.linalg.pinv(sol.jac.T @ sol.jac)
    sig = np.sqrt(np.clip(np.diag(cov), 0, None))
    if not np.all(np.isfinite(sig)) or sig[:3].max() > MAX_BIAS_SIGMA or sig[3:].max() > MAX_SCALE_SIGMA:
        d = -f / np.linalg.norm(f, axis=1, keepdims=True)
        mean = d.mean(axis=0) / np.linalg.norm(d.mean(axis=0))
        span = float(np.degrees(np.arccos(np.clip(d @ mean, -1, 1)).max()))
        raise AnalysisError(f"accelerometer norm fit: the {k} still orientations (gravity within {span:.0f}° of their "
                            f"mean direction) do not determine bias and scale factors (largest sigma: bias "
                            f"{sig[:3].max():.3g} m/s², scale/misalignment {sig[3:].max():.3g}); set the unit down with "
                            "each axis up and down")
    b, mm = unpack(sol.x)
    m_sig = _sym(sig[3:]) if full else np.where(np.eye(3, dtype=bool), np.diag(sig[3:6]), np.nan)
    comp = np.linalg.solve(np.eye(3) + mm, (f - b).T).T
    ref = gravity * comp / np.linalg.norm(comp, axis=1, keepdims=True)
    table = _residual_table(means, ref, f - ref, comp - ref, np.array([m.accel_sigma for m in means]),
                            np.linalg.norm(f, axis=1) - gravity, r)
    notes = {"method": f"gravity-norm fit on {k} still stretches ({n_par} parameters; no orientation known, "
                       "the rotation part of the misalignment is not observable)"}
    warnings = () if full else (f"{k} still orientations: bias and scale factors only (misalignment needs "
                                f"{MIN_FULL})",)
    return TriadFit("accel", b, mm, np.zeros(3), None, sig[:3], m_sig, _NAN3.copy(), None, residuals=table,
                    warnings=warnings, chi2_reduced=float(r @ r) / max(dof, 1) / noise**2 if noise > 0 else np.nan,
                    dof=max(dof, 0), notes=notes)


def fit_gyro_bias(means: list[StillMean], latitude: float, g_sensitivity: np.ndarray | float | None = None) -> TriadFit:
    """Gyro bias (3,) rad/s from the still stretches, Earth rate and g-sensitivity handled as in the module docstring.

    ``latitude`` rad (the site's). The down direction of each stretch is its mean specific force's.
    ``g_sensitivity`` rad/s per m/s^2: the 1-sigma spread of each element of ``G`` per row (3,) or for
    all (the grade's ``TriadSpec.g_sensitivity``); None: :data:`G_SENSITIVITY_BOUND`.
    """
    if not means:
        raise AnalysisError("gyro bias: no still stretch in the free steps (hold the unit still for a second or more)")
    w = np.array([m.gyro for m in means])
    down = -np.array([m.accel for m in means])
    down /= np.linalg.norm(down, axis=1, keepdims=True)
    vertical = -EARTH_RATE * np.sin(latitude) * down  # NED Earth rate's down component, in the body axes
    corrected = w - vertical
    n = np.array([m.n for m in means], float)
    bias = (corrected * n[:, None]).sum(axis=0) / n.sum()
    # sigma of the sample-weighted mean of the stretch means, each with its own correlation time
    white = np.sqrt(sum((m.n * m.gyro_sigma) ** 2 for m in means)) / n.sum()
    horizontal = EARTH_RATE * np.cos(latitude) * np.sqrt((1 - (down**2).mean(axis=0)) / 2)
    k = len(means)
    scatter = corrected.std(axis=0, ddof=1) / np.sqrt(k) if k > 1 else np.zeros(3)
    f_mean = (np.array([m.accel for m in means]) * n[:, None]).sum(axis=0) / n.sum()
    s_g = np.broadcast_to(np.asarray(G_SENSITIVITY_BOUND if g_sensitivity is None else g_sensitivity, float), (3,))
    g_term = s_g * np.linalg.norm(f_mean)
    sigma = np.sqrt(np.maximum(white, scatter) ** 2 + horizontal**2 / k + g_term**2)
    table = _residual_table(means, vertical, w - vertical, corrected - bias,
                            np.array([m.gyro_sigma for m in means]),
                            np.full(k, np.nan), np.full(k, np.nan))
    source = "the unit's grade" if g_sensitivity is not None else "a consumer MEMS gyro's datasheet bound"
    notes = {"earth_rate": "vertical part removed along the measured down direction; horizontal part "
                           "(heading unknown) in the sigma",
             "g_sensitivity": f"not observed (no orientation known, not fitted): the bias holds G f at the "
                              f"stretches' mean specific force; its sigma carries "
                              f"{to_unit(s_g.max(), 'deg/s/g'):.3g} °/s/g x {np.linalg.norm(f_mean) / G0:.2f} g "
                              f"({source})",
             "method": f"mean of {k} still stretch(es), {int(n.sum())} samples",
             # rad/s, the g-sensitivity part of bias_sigma: common to every record held in the same orientations
             "bias_sigma_g_sensitivity": g_term.tolist()}
    return TriadFit("gyro", bias, np.zeros((3, 3)), np.zeros(3), None, sigma, np.full((3, 3), np.nan),
                    _NAN3.copy(), None, residuals=table, dof=max(k - 1, 0), notes=notes)
