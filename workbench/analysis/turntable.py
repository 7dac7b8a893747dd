"""Turntable calibration estimators: multi-position static fits and rate-table fits.

Estimators for the deterministic errors of an accelerometer or gyro triad from a session
recorded on a turntable (thesis sec. 1.3, shared/seeds/000_...), in the one model of
:mod:`workbench.model`::

    measured = (I + M) x + n * u**2 + b + G f + noise,     u = (I + M) x

- :func:`fit_accel`: static positions; ``x`` = local normal gravity (site) rotated into the
  body by the step's mount and table angle (specific force, body frame). Bias, full ``M``,
  per-axis nonlinearity when the positions put at least two distinct non-zero inputs on the axis.
- :func:`fit_gyro_static`: static positions; bias and g-sensitivity ``G``, with the Earth-rate
  projection ``C_bn' w_ie`` (needs the table zero azimuth) or, without it, the statement that
  the bias and ``G`` absorb the Earth rate.
- :func:`fit_gyro_rate`: constant-rate steps over whole revolutions against the encoder rate
  (samples column ``table_rate``) plus the vertical Earth rate; ``M``, nonlinearity, and
  asymmetry (separate scale factors for positive and negative rates), with one offset per
  mount as a nuisance (bias + G f); bias and ``G`` from the offsets when the mounts observe them.

Each axis (row of the model) is a separate weighted least-squares problem solved by
Gauss-Newton; weights are the variances of the step means from a white + bias-instability
noise model (:func:`workbench.analysis.position_check.mean_variance`). The covariance
``(J' W J)^-1`` is scaled by the Birge ratio ``max(1, chi2 / dof)`` pooled over the three axes,
so scatter between positions that the noise model does not explain (fixture and positioning
errors, drift) widens the 1-sigma uncertainties; the bias also carries the wander of the bias
common to all positions (:func:`bias_wander`: the noise floor plus the between-position
variance of :func:`between_step_variance`), which no scatter about the fit can show.
Parameters that the position set cannot observe are reported with NaN sigma and their prior
value (0), with a warning when they were requested. A position that does not fit is found by leave-one-out residuals
(:func:`workbench.analysis.position_check.deleted_residual_statistics`) and named.

Public: :class:`TriadFit`, :func:`fit_accel`, :func:`fit_gyro_static`, :func:`fit_gyro_rate`,
:func:`between_step_variance`, :func:`bias_wander`, :func:`hidden_bias_instability`,
:func:`hidden_floor_warning`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd
from scipy.optimize import brentq
from scipy.stats import chi2 as chi2_dist

from workbench.analysis.northfinding_theory import FLICKER_AVAR
from workbench.analysis.position_check import (
    MeanNoise, StepStats, deleted_residual_statistics, mean_variance, motion_in_static, static_mean_variance,
    step_name, step_stats, whole_revolution_samples, whole_revolutions,
)
from workbench import units
from workbench.calset import TriadCalibration
from workbench.earth import EARTH_RATE, earth_rate_ned
from workbench.errors import AnalysisError
from workbench.model import TriadModel
from workbench.session import Session, StepRecord

AXES = "xyz"
STATIC_KINDS = ("static", "soak")
MISFIT_P = 1e-4  # false-alarm probability of the misfit test per session (Bonferroni over positions)
POOL_DOF = 10  # fewer residual degrees of freedom on an axis: its between-step variance is pooled over the triad
_NAN3 = np.full(3, np.nan)
_NAN33 = np.full((3, 3), np.nan)


@dataclass(frozen=True)
class TriadFit:
    """Result of a turntable fit of one triad (SI, body frame; NaN sigma = not observed).

    ``bias`` (3,), ``scale_misalignment`` ``M`` (3, 3), ``nonlinearity`` (3,) 1/SI,
    ``g_sensitivity`` (3, 3) rad/s per m/s^2 (gyro) or None, ``asymmetry`` (3,) half the
    difference of the positive- and negative-rate scale-factor errors (SF+ = M_ii + asym,
    SF- = M_ii - asym), each with a ``*_sigma`` of the same shape.
    ``residuals``: one row per step with ``step``, ``label``, ``used``, reference input
    ``ref_x..z``, ``before_x..z`` (raw mean - reference), ``after_x..z`` (compensated mean -
    reference), ``sigma_x..z`` (1-sigma of the raw mean, Birge-scaled) and ``before_norm`` /
    ``after_norm`` (norm of the mean minus norm of the reference), all SI.
    ``outliers``: indices of steps that do not fit (named in ``warnings``).
    ``chi2_reduced``/``dof``: fit quality (pooled over axes); ``notes`` method facts (e.g.
    how the Earth rate was handled).
    """

    triad: str
    bias: np.ndarray
    scale_misalignment: np.ndarray
    nonlinearity: np.ndarray
    g_sensitivity: np.ndarray | None
    bias_sigma: np.ndarray
    scale_misalignment_sigma: np.ndarray
    nonlinearity_sigma: np.ndarray
    g_sensitivity_sigma: np.ndarray | None
    asymmetry: np.ndarray = field(default_factory=lambda: np.zeros(3))
    asymmetry_sigma: np.ndarray = field(default_factory=lambda: _NAN3.copy())
    residuals: pd.DataFrame = field(default_factory=pd.DataFrame)
    outliers: tuple[int, ...] = ()
    warnings: tuple[str, ...] = ()
    chi2_reduced: float = float("nan")
    dof: int = 0
    notes: Mapping[str, object] = field(default_factory=dict)

    def model(self) -> TriadModel:
        """The fitted :class:`TriadModel` (unobserved coefficients at their prior, 0)."""
        return TriadModel(self.bias, self.scale_misalignment, self.nonlinearity, self.g_sensitivity)

    def to_calibration(self) -> TriadCalibration:
        """A :class:`workbench.calset.TriadCalibration` with the 1-sigma uncertainties."""
        sigma = {"bias": self.bias_sigma, "scale_misalignment": self.scale_misalignment_sigma,
                 "nonlinearity": self.nonlinearity_sigma}
        if self.g_sensitivity is not None:
            sigma["g_sensitivity"] = self.g_sensitivity_sigma
        return TriadCalibration(self.model(), sigma)

    def to_dict(self) -> dict:
        """JSON-ready summary (SI, NaN -> None), without the residual table."""
        def arr(a):
            if a is None:
                return None
            a = np.asarray(a, float)
            return [arr(row) for row in a] if a.ndim == 2 else [float(v) if np.isfinite(v) else None for v in a]

        out = {"triad": self.triad}
        for name in ("bias", "scale_misalignment", "nonlinearity", "g_sensitivity", "asymmetry"):
            out[name] = arr(getattr(self, name))
            out[name + "_sigma"] = arr(getattr(self, name + "_sigma"))
        out.update({"outliers": list(self.outliers), "warnings": list(self.warnings),
                    "chi2_reduced": None if not np.isfinite(self.chi2_reduced) else float(self.chi2_reduced),
                    "dof": int(self.dof), "notes": dict(self.notes)})
        return out


# -- shared machinery ------------------------------------------------------------------------

@dataclass
class _AxisFit:
    """Per-axis Gauss-Newton WLS solution: parameters, scaled covariance, column names."""

    beta: list[np.ndarray]
    cov: list[np.ndarray]
    names: list[list[str]]
    chi2: float
    dof: int
    scale: float
    jac: list[np.ndarray]
    y_lin: np.ndarray
    chi2_axes: np.ndarray = field(default_factory=lambda: np.zeros(3))
    dof_axes: np.ndarray = field(default_factory=lambda: np.zeros(3, int))
    dropped: set[str] = field(default_factory=set)


def check_site(session: Session) -> None:
    """Raise AnalysisError if the session's site has no usable latitude."""
    lat = session.site.latitude_deg
    if lat is None or not np.isfinite(lat):
        raise AnalysisError(f"{session.name}: site.latitude_deg is missing: local gravity and Earth rate unknown")


def _full_rank(x: np.ndarray, var: np.ndarray) -> bool:
    a = x / np.sqrt(var)[:, None]
    norms = np.linalg.norm(a, axis=0)
    if np.any(norms == 0):
        return False
    return np.linalg.matrix_rank(a / norms, tol=1e-9 * x.shape[0]) == x.shape[1]


def _gauss_newton(model, beta0: list[np.ndarray], names: list[list[str]], y: np.ndarray, var: np.ndarray,
                  iterations: int = 6) -> _AxisFit:
    """Solve each axis ``y[:, j] ~ h_j(beta_j)`` by weighted Gauss-Newton.

    ``model(j, beta_j) -> (h (n,), J (n, p))``. Covariance scaled by max(1, pooled chi2/dof).
    """
    betas, covs, jacs = [], [], []
    chi2_axes, dof_axes = np.zeros(3), np.zeros(3, int)
    y_lin = np.zeros_like(y)
    for j in range(3):
        beta = np.array(beta0[j], float)
        w = 1.0 / var[:, j]
        for _ in range(iterations):
            h, jac = model(j, beta)
            step, *_ = np.linalg.lstsq(jac * np.sqrt(w)[:, None], (y[:, j] - h) * np.sqrt(w), rcond=None)
            beta = beta + step
            if np.all(np.abs(step) < 1e-14 * (1 + np.abs(beta))):
                break
        h, jac = model(j, beta)
        a = jac * np.sqrt(w)[:, None]
        covs.append(np.linalg.inv(a.T @ a))
        chi2_axes[j] = float(np.sum((y[:, j] - h) ** 2 * w))
        dof_axes[j] = y.shape[0] - beta.size
        betas.append(beta)
        jacs.append(jac)
        y_lin[:, j] = y[:, j] - h + jac @ beta
    chi2, dof = float(chi2_axes.sum()), int(dof_axes.sum())
    scale = max(1.0, chi2 / dof) if dof > 0 else 1.0
    return _AxisFit(betas, [c * scale for c in covs], names, chi2, dof, scale, jacs, y_lin, chi2_axes, dof_axes)


def _drop_unobservable(designs: list[np.ndarray], names: list[list[str]], var: np.ndarray,
                       droppable: Sequence[str], context: str) -> tuple[list[list[int]], set[str]]:
    """Columns to keep per axis so each design has full rank, dropping ``droppable`` prefixes in order.

    Raises AnalysisError (naming ``context``) if the core columns alone are rank deficient.
    """
    keep_all, dropped = [], set()
    for j, x in enumerate(designs):
        keep = list(range(x.shape[1]))
        for prefix in droppable:
            if _full_rank(x[:, keep], var[:, j]):
                break
            cand = [k for k in keep if names[j][k].startswith(prefix)]
            # drop the candidates one at a time, keeping those that do not cost rank
            for k in cand:
                trial = [c for c in keep if c != k]
                if np.linalg.matrix_rank(x[:, trial] / np.sqrt(var[:, j])[:, None]) == np.linalg.matrix_rank(
                        x[:, keep] / np.sqrt(var[:, j])[:, None]):
                    keep = trial
                    dropped.add(names[j][k])
        if not _full_rank(x[:, keep], var[:, j]):
            raise AnalysisError(f"{context}: the steps cannot observe the {AXES[j]} axis "
                                f"({x.shape[0]} steps for {len(keep)} parameters: "
                                f"{', '.join(names[j][k] for k in keep)})")
        keep_all.append(keep)
    return keep_all, dropped


def _misfits(fit: _AxisFit, var: np.ndarray, stats: list[StepStats], residual_of) -> tuple[list[int], str]:
    """Rows that do not fit (leave-one-out test), and a warning naming the steps ('' if none).

    ``residual_of(i)`` describes row ``i``'s residual for the warning (lab units).
    """
    n = len(stats)
    t = deleted_residual_statistics(fit.jac, fit.y_lin, var)
    limit = chi2_dist.isf(MISFIT_P / n, 3)
    flagged = [i for i in np.argsort(-np.nan_to_num(t, nan=-1.0)) if np.isfinite(t[i]) and t[i] > limit]
    if not flagged:
        return [], ""
    worst = flagged[0]
    names = ", ".join(f"{step_name(stats[i].step)}: residual {residual_of(i)} ({np.sqrt(t[i]):.0f} sigma)"
                      for i in flagged)
    if len(flagged) == 1:
        return [worst], f"does not fit the model: {names}"
    return flagged, (f"{len(flagged)} steps do not fit the model: {names}; this position set cannot tell whether one "
                     "mis-mounted position or several cause it")


def _mount_key(mount: np.ndarray) -> tuple:
    return tuple(np.round(np.asarray(mount), 6).ravel())


def _residual_frame(stats: list[StepStats], ref: np.ndarray, raw: np.ndarray, comp: np.ndarray,
                    var: np.ndarray, used: np.ndarray) -> pd.DataFrame:
    rows = {"step": [s.step.index for s in stats], "label": [s.step.label or s.step.kind for s in stats],
            "kind": [s.step.kind for s in stats], "used": used}
    for j, ax in enumerate(AXES):
        rows[f"ref_{ax}"] = ref[:, j]
        rows[f"before_{ax}"] = raw[:, j] - ref[:, j]
        rows[f"after_{ax}"] = comp[:, j] - ref[:, j]
        rows[f"sigma_{ax}"] = np.sqrt(var[:, j])
    rows["before_norm"] = np.linalg.norm(raw, axis=1) - np.linalg.norm(ref, axis=1)
    rows["after_norm"] = np.linalg.norm(comp, axis=1) - np.linalg.norm(ref, axis=1)
    return pd.DataFrame(rows)


def _static_stats(session: Session, steps: Sequence[int] | None, settle_s: float,
                  what: str) -> tuple[list[StepStats], list[str]]:
    """Static steps to use (all static/soak steps when ``steps`` is None), with motion warnings."""
    check_site(session)
    if steps is None:
        recs = session.steps_of_kind(*STATIC_KINDS)
    else:
        recs = [session.step(i) for i in steps]
        bad = [r for r in recs if r.kind not in STATIC_KINDS]
        if bad:
            raise AnalysisError(f"{session.name}: {step_name(bad[0])} is a {bad[0].kind} step, not static ({what})")
    warnings, used = [], []
    for r in recs:
        reason = motion_in_static(session, r, settle_s)
        if reason:
            warnings.append(f"{reason}: excluded from the {what}")
        else:
            used.append(step_stats(session, r, settle_s))
    if len(used) < 4:
        raise AnalysisError(f"{session.name}: {what}: {len(used)} usable static position(s); bias and the 3x3 "
                            "scale/misalignment need at least 4 positions spanning all three axes (6 recommended)"
                            + (f" ({'; '.join(warnings)})" if warnings else ""))
    return used, warnings


def _specific_force(session: Session, stats: list[StepStats]) -> np.ndarray:
    """True specific force (n, 3), body frame, m/s^2, from the site's normal gravity and the mounts."""
    up = np.array([0.0, 0.0, -session.site.gravity])
    return np.array([session.table_attitude(s.step, _angle(s)).inv().apply(up) for s in stats])


def _angle(s: StepStats) -> float:
    return s.table_angle if np.isfinite(s.table_angle) else s.step.table_angle


def _sigma_matrix(fit: _AxisFit, prefix: str, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Values and sigmas (3, width) of columns named ``prefix{k}`` (0 and NaN sigma where not kept)."""
    val, sig = np.zeros((3, width)), np.full((3, width), np.nan)
    for j in range(3):
        for k in range(width):
            name = f"{prefix}{k}" if width > 1 else prefix
            if name in fit.names[j]:
                c = fit.names[j].index(name)
                val[j, k], sig[j, k] = fit.beta[j][c], np.sqrt(fit.cov[j][c, c])
    return val, sig


def _fit_with_misfits(build, stats: list[StepStats], y: np.ndarray, var: np.ndarray, context: str,
                      residual_of) -> tuple[_AxisFit, np.ndarray, list[int], list[str]]:
    """Fit, test for rows that do not fit, refit without a single clearly identified misfit."""
    fit = build(np.ones(len(stats), bool))
    bad, msg = _misfits(fit, var, stats, residual_of(fit))
    used = np.ones(len(stats), bool)
    warnings = []
    if len(bad) == 1:
        trial = used.copy()
        trial[bad[0]] = False
        try:
            fit = build(trial)
            used = trial
            warnings.append(f"{context}: {msg}; excluded (mounting or fixture error?)")
        except AnalysisError:
            warnings.append(f"{context}: {msg}; kept, the other steps cannot observe the model without it")
    elif bad:
        warnings.append(f"{context}: {msg}; all kept, the estimates are suspect")
    return fit, used, bad, warnings


# -- accelerometer -----------------------------------------------------------------------------

def fit_accel(session: Session, steps: Sequence[int] | None = None, nonlinearity: str = "auto",
              settle_s: float = 1.0, position_sigma: float | str = 0.0,
              bias_instability: np.ndarray | float | None = None, warn_hidden_floor: bool = True) -> TriadFit:
    """Accelerometer bias, ``M`` and nonlinearity from static positions (body frame, SI).

    ``steps``: indices of static steps (None = all static and soak steps). ``nonlinearity``:
    ``"auto"`` fits it on the axes where the positions put at least two distinct non-zero
    inputs (e.g. 1 g and 0.71 g from 12/18/24-position sets), ``"fit"`` the same but warns for
    the axes where it cannot (a 6-position set only has 0 and ±1 g, where a quadratic term
    cannot be told from a bias that depends on orientation), ``"none"`` never.
    ``settle_s`` s are dropped at the start of each step. Reference: the site's normal gravity
    as specific force, rotated into the body by the step's mount and table angle.

    ``position_sigma`` (rad, 1-sigma tilt of each position about the horizontal axes): 0 for
    a turntable fixture; a tilt ``e`` moves the input by ``g e`` across gravity and only
    ``g e^2 / 2`` along it, so row ``j`` of position ``i`` gets the extra variance
    ``g^2 s^2 (1 - u_ij^2) + g^2 s^4 u_ij^2`` (``u`` = unit gravity direction, body). ``"auto"``
    (hand-made positions) estimates ``s`` so that chi2/dof = 1 when the scatter exceeds the
    noise (chi2 beyond its 99.9 % point); the bias then comes mostly from each axis's own
    up/down pair, as in the classical six-position method.

    ``bias_instability`` (m/s^2, scalar or (3,)): the unit's bias instability ``B`` (IEEE 952,
    from its Allan characterisation); it sets a lower bound ``0.664 B`` on the bias-wander floor
    of the step means, for dwells too short to show it (see :func:`bias_wander`). Without it a
    warning (unless ``warn_hidden_floor`` is False: a caller summarising many fits) gives the
    largest ``B`` the dwells could hide when that would exceed the bias sigma; it is also in
    ``notes["hidden_bias_instability"]``.
    """
    if nonlinearity not in ("auto", "fit", "none"):
        raise AnalysisError(f"nonlinearity={nonlinearity!r}: expected 'auto', 'fit' or 'none'")
    context = f"{session.name}: accelerometer fit"
    stats, warnings = _static_stats(session, steps, settle_s, "accelerometer fit")
    f = _specific_force(session, stats)
    y = np.array([s.accel for s in stats])
    noise = _static_noise(session, stats, "accel", settle_s, bias_instability, context)
    var = noise.variance
    g = session.site.gravity
    levels = [np.unique(np.round(np.abs(f[:, j]) / g, 2)) for j in range(3)]
    nl_axes = [nonlinearity != "none" and int(np.sum(lv > 0.1)) >= 2 for lv in levels]
    if nonlinearity == "fit":
        for j in range(3):
            if not nl_axes[j]:
                warnings.append(f"{context}: nonlinearity of the {AXES[j]} axis not observable: the positions give "
                                f"inputs of only {', '.join(f'{v:g}' for v in levels[j])} g (use a 12-, 18- or "
                                "24-position set)")

    u2 = (f / g) ** 2

    def position_var(sig: float) -> np.ndarray:
        return var + g**2 * sig**2 * (1 - u2) + g**2 * sig**4 * u2

    def build(rows: np.ndarray, sig: float | None = None) -> _AxisFit:
        fr = f[rows]
        vr = position_var(tilt if sig is None else sig)[rows]
        names = [["bias", "m0", "m1", "m2"] + (["n"] if nl_axes[j] else []) for j in range(3)]

        def model(j, beta):
            a = np.eye(3)[j] + beta[1:4]
            u = fr @ a
            nl = beta[4] if nl_axes[j] else 0.0
            cols = [np.ones(len(fr)), fr * (1 + 2 * nl * u)[:, None]] + ([(u**2)[:, None]] if nl_axes[j] else [])
            return beta[0] + u + nl * u**2, np.column_stack(cols)

        designs = [model(j, np.zeros(len(names[j])))[1] for j in range(3)]
        _drop_unobservable(designs, names, vr, droppable=(), context=context)
        return _gauss_newton(model, [np.zeros(len(n)) for n in names], names, y[rows], vr)

    tilt = _position_sigma(build, position_sigma, len(stats), context)
    if tilt > 0 and position_sigma == "auto":
        warnings.append(f"{context}: positions scatter beyond the sensor noise: a tilt of {1e3 * tilt:.3g} mrad "
                        f"({np.degrees(tilt):.2g}°) 1-sigma per position is estimated (hand-made or loose fixture)")

    def residual_of(fit):
        return lambda i: units.fmt(np.linalg.norm(_accel_after(fit, y[i:i + 1], f[i:i + 1])), "mg", 3)

    fit, used, outliers, w2 = _fit_with_misfits(build, stats, y, position_var(tilt), context, residual_of)
    warnings += w2
    between = between_step_variance(fit, position_var(tilt)[used])
    result = _with_bias_wander(_accel_result(fit), noise, between)
    hidden, w3 = _hidden_floor(noise, result, stats, session.sample_rate_hz, "mg", context, bias_instability,
                               warn_hidden_floor)
    warnings += w3
    comp = result.model().compensate(y)
    return replace(result, residuals=_residual_frame(stats, f, y, comp, position_var(tilt) * fit.scale, used),
                        outliers=tuple(stats[i].step.index for i in outliers), warnings=tuple(warnings),
                        chi2_reduced=fit.chi2 / fit.dof if fit.dof else float("nan"), dof=fit.dof,
                        notes={"gravity_m_s2": g, "positions": int(used.sum()), "position_sigma_rad": tilt,
                               **_noise_notes(noise, between, hidden),
                               "nonlinearity_axes": [AXES[j] for j in range(3) if nl_axes[j]]})


def between_step_variance(axes: _AxisFit, var: np.ndarray) -> np.ndarray:
    """Between-step (random-effects) variance (3,) SI^2 of the step means beyond ``var``.

    Bias instability and rate random walk move the bias from one position to the next by
    about the Allan deviation at the dwell time, which the within-step noise model of a short
    dwell misses (its floor ``F`` is kept only when the Allan variance at ``T/4`` shows it).
    Paule-Mandel estimate: the ``c >= 0`` with ``sum r^2 / (var + c) = dof`` (``r`` the fit's
    residuals, ``var`` the variances it used, (n_used, 3)); 0 when the scatter is within the
    noise model (``chi2 <= dof``). Per axis when the axis has at least :data:`POOL_DOF` degrees
    of freedom (18 and 24 positions), else pooled over the three axes (one wander level for the
    triad): a variance from 2 degrees of freedom (an axis of a six-position fit) has a relative
    standard error of 100 %.
    """
    r2 = np.column_stack([(axes.y_lin[:, j] - axes.jac[j] @ axes.beta[j]) ** 2 for j in range(3)])

    def paule_mandel(cols: list[int]) -> float:
        d = int(sum(axes.dof_axes[j] for j in cols))
        rc, vc = r2[:, cols], var[:, cols]
        if d <= 0 or float(np.sum(rc / vc)) <= d:
            return 0.0
        return float(brentq(lambda c: float(np.sum(rc / (vc + c))) - d, 0.0, float(rc.max()) * rc.size))

    pooled = paule_mandel([0, 1, 2])
    return np.array([paule_mandel([j]) if axes.dof_axes[j] >= POOL_DOF else pooled for j in range(3)])


def bias_wander(noise: MeanNoise, between: np.ndarray) -> np.ndarray:
    """Variance (3,) SI^2 of the session's mean bias about the bias at the session start.

    The fit treats step errors as independent, but bias instability and rate random walk are
    largely common to all steps, so the session's mean bias departs from the bias at its start
    by about their level at the dwell time whatever the number of positions (flat Allan
    variance: the common part of the wander is as large as the part that differs between
    steps). That level: the noise floor ``F`` of the step means plus the ``between``-step
    variance (:func:`between_step_variance`).
    """
    return noise.floor**2 + between


def _with_bias_wander(fit: TriadFit, noise: MeanNoise, between: np.ndarray) -> TriadFit:
    """The fit with :func:`bias_wander` added to the bias variance."""
    return replace(fit, bias_sigma=np.sqrt(fit.bias_sigma**2 + bias_wander(noise, between)))


def _static_noise(session: Session, stats: list[StepStats], triad: str, settle_s: float,
                  bias_instability: np.ndarray | float | None, context: str) -> MeanNoise:
    """Noise of the static step means, its floor raised to the unit's ``bias_instability`` (SI) if given."""
    noise = static_mean_variance(session, stats, triad, settle_s)
    if bias_instability is None:
        return noise
    b = np.asarray(bias_instability, float)
    if b.size not in (1, 3) or not np.all(b >= 0):
        raise AnalysisError(f"{context}: bias_instability {b.ravel().tolist()} (SI) must be >= 0, one value or three")
    return noise.with_floor(np.sqrt(FLICKER_AVAR) * b.ravel())


def hidden_bias_instability(noise: MeanNoise, bias_sigma: np.ndarray) -> np.ndarray:
    """The largest bias instability ``B`` (3,) SI that the dwells cannot show (an Allan floor under
    :attr:`MeanNoise.floor_limit`), on the axes where it would exceed ``bias_sigma``; NaN elsewhere."""
    hidden = (noise.floor == 0) & (noise.floor_limit > bias_sigma)
    return np.where(hidden, noise.floor_limit / np.sqrt(FLICKER_AVAR), np.nan)


def hidden_floor_warning(hidden: np.ndarray, bias_sigma: np.ndarray | None, dwell_s: float, unit: str,
                         context: str) -> list[str]:
    """A warning naming the axes of :func:`hidden_bias_instability` (lab ``unit``; with the bias sigma
    when given), [] when none."""
    if not np.isfinite(hidden).any():
        return []
    axes = ", ".join(f"{AXES[j]} {units.fmt(hidden[j], unit, 2)}"
                     + ("" if bias_sigma is None else f" (bias sigma {units.fmt(bias_sigma[j], unit, 2)})")
                     for j in range(3) if np.isfinite(hidden[j]))
    return [f"{context}: a bias instability up to {axes} would not show in {dwell_s:.3g}-s dwells: the bias sigma "
            "does not include one; give the unit's bias instability (its Allan result) or dwell longer"]


def _hidden_floor(noise: MeanNoise, bias: TriadFit, stats: list[StepStats], fs: float, unit: str, context: str,
                  bias_instability, warn: bool) -> tuple[np.ndarray, list[str]]:
    """:func:`hidden_bias_instability` (all NaN when the unit's ``bias_instability`` was given) and,
    if ``warn``, its warning."""
    hidden = np.full(3, np.nan) if bias_instability is not None else hidden_bias_instability(noise, bias.bias_sigma)
    dwell = min(s.n for s in stats) / fs
    return hidden, hidden_floor_warning(hidden, bias.bias_sigma, dwell, unit, context) if warn else []


def _noise_notes(noise, between: np.ndarray | None = None, hidden: np.ndarray | None = None) -> dict:
    """Noise model of the step means for ``notes``: white density (SI/√Hz), bias-wander floor (SI)
    and, for static fits, the between-step deviation (SI, random effect) and the bias instability
    the dwells could hide (SI, None where it could not matter: :func:`hidden_bias_instability`)."""
    out = {"noise_white_density": noise.white.tolist(), "noise_floor": noise.floor.tolist()}
    if between is not None:
        out["between_step_sigma"] = np.sqrt(between).tolist()
    if hidden is not None:
        out["hidden_bias_instability"] = [float(v) if np.isfinite(v) else None for v in hidden]
    return out


def _position_sigma(build, position_sigma: float | str, n: int, context: str) -> float:
    """The position tilt sigma (rad): given, or for ``"auto"`` the one making chi2/dof = 1."""
    if position_sigma != "auto":
        sig = float(position_sigma)
        if not sig >= 0:
            raise AnalysisError(f"{context}: position_sigma={position_sigma!r} must be >= 0 rad or 'auto'")
        return sig
    fit0 = build(np.ones(n, bool), 0.0)
    if fit0.dof == 0 or fit0.chi2 <= chi2_dist.isf(1e-3, fit0.dof):
        return 0.0

    def excess(log_sig: float) -> float:
        fit = build(np.ones(n, bool), float(np.exp(log_sig)))
        return fit.chi2 / fit.dof - 1.0

    return float(np.exp(brentq(excess, np.log(1e-7), np.log(0.3), xtol=1e-4)))


def _accel_after(fit: _AxisFit, y: np.ndarray, f: np.ndarray) -> np.ndarray:
    return _accel_result(fit).model().compensate(y) - f


def _accel_result(fit: _AxisFit) -> TriadFit:
    bias, bias_s = _sigma_matrix(fit, "bias", 1)
    m, m_s = _sigma_matrix(fit, "m", 3)
    n, n_s = _sigma_matrix(fit, "n", 1)
    return TriadFit("accel", bias[:, 0], m, n[:, 0], None, bias_s[:, 0], m_s, n_s[:, 0], None)


# -- gyro, static ------------------------------------------------------------------------------

def fit_gyro_static(session: Session, steps: Sequence[int] | None = None, earth_rate: str = "auto",
                    settle_s: float = 1.0, scale_misalignment: np.ndarray | None = None,
                    bias_instability: np.ndarray | float | None = None, warn_hidden_floor: bool = True) -> TriadFit:
    """Gyro bias and g-sensitivity ``G`` from static positions (rad/s, rad/s per m/s^2, body frame).

    ``earth_rate``: ``"model"`` subtracts the Earth-rate projection ``(C_bn)' w_ie^n`` (needs the
    site's table zero azimuth), ``"ignore"`` leaves it in the data (bias and ``G`` absorb up to
    15 °/h), ``"auto"`` models it when the azimuth is known and says so when not.
    ``scale_misalignment``: ``M`` from a rate fit, used to project the Earth rate through
    ``I + M`` (default 0: an error of ``M`` x 15 °/h, 0.015 °/h for M = 1e-3).
    ``bias_instability`` (rad/s) and ``warn_hidden_floor``: as for :func:`fit_accel`.
    ``M`` and nonlinearity are not observed here (NaN sigma).
    """
    if earth_rate not in ("auto", "model", "ignore"):
        raise AnalysisError(f"earth_rate={earth_rate!r}: expected 'auto', 'model' or 'ignore'")
    context = f"{session.name}: gyro static fit"
    stats, warnings = _static_stats(session, steps, settle_s, "gyro static fit")
    az_known = session.site.table_zero_azimuth is not None
    if earth_rate == "model" and not az_known:
        raise AnalysisError(f"{context}: earth_rate='model' needs site.table_zero_azimuth_deg (it is null)")
    use_earth = earth_rate == "model" or (earth_rate == "auto" and az_known)
    f = _specific_force(session, stats)
    w_ie = earth_rate_ned(session.site.latitude)
    gain = np.eye(3) + (np.zeros((3, 3)) if scale_misalignment is None else np.asarray(scale_misalignment, float))
    ref = (np.array([session.attitude(s.step, _angle(s)).inv().apply(w_ie) for s in stats]) @ gain.T if use_earth
           else np.zeros((len(stats), 3)))
    y = np.array([s.gyro for s in stats])
    noise = _static_noise(session, stats, "gyro", settle_s, bias_instability, context)
    var = noise.variance

    def build(rows: np.ndarray) -> _AxisFit:
        fr = f[rows]
        x = np.column_stack([np.ones(len(fr)), fr])
        names = [["bias", "g0", "g1", "g2"] for _ in range(3)]
        keep, _ = _drop_unobservable([x] * 3, names, var[rows], droppable=("g",), context=context)
        names = [[names[j][k] for k in keep[j]] for j in range(3)]

        def model(j, beta):
            xj = x[:, keep[j]]
            return ref[rows, j] + xj @ beta, xj

        return _gauss_newton(model, [np.zeros(len(n)) for n in names], names, y[rows], var[rows], iterations=2)

    def residual_of(fit):
        return lambda i: units.fmt(np.linalg.norm(y[i] - ref[i] - _gyro_static_result(fit).bias), "deg/h", 3)

    fit, used, outliers, w2 = _fit_with_misfits(build, stats, y, var, context, residual_of)
    warnings += w2
    between = between_step_variance(fit, var[used])
    result = _with_bias_wander(_gyro_static_result(fit), noise, between)
    hidden, w3 = _hidden_floor(noise, result, stats, session.sample_rate_hz, "deg/h", context, bias_instability,
                               warn_hidden_floor)
    warnings += w3
    if np.isnan(result.g_sensitivity_sigma).any():
        warnings.append(f"{context}: g-sensitivity partly not observed by these positions (NaN sigma)")
    comp = result.model().compensate(y, specific_force=f)
    notes: dict = {"positions": int(used.sum()), **_noise_notes(noise, between, hidden)}
    worst_sigma = float(np.nanmax(result.bias_sigma))
    if use_earth:
        notes["earth_rate"] = "modelled: Earth-rate projection subtracted at each position"
    else:
        notes["earth_rate"] = "not modelled: bias and g-sensitivity absorb the Earth rate (up to 15.04 °/h)"
        if worst_sigma < EARTH_RATE:
            why = "table zero azimuth unknown" if not az_known else "earth_rate=ignore"
            warnings.append(f"{context}: Earth rate not modelled ({why}): bias (sigma "
                            f"{np.degrees(worst_sigma) * 3600:.2g} °/h) and g-sensitivity absorb up to 15 °/h")
    if worst_sigma > EARTH_RATE:
        notes["earth_rate"] += (f"; the bias noise ({np.degrees(worst_sigma) * 3600:.3g} °/h) exceeds the Earth rate "
                                "at this grade")
    return replace(result, residuals=_residual_frame(stats, ref, y, comp, var * fit.scale, used),
                        outliers=tuple(stats[i].step.index for i in outliers), warnings=tuple(warnings),
                        chi2_reduced=fit.chi2 / fit.dof if fit.dof else float("nan"), dof=fit.dof, notes=notes)


def _gyro_static_result(fit: _AxisFit) -> TriadFit:
    bias, bias_s = _sigma_matrix(fit, "bias", 1)
    g, g_s = _sigma_matrix(fit, "g", 3)
    return TriadFit("gyro", bias[:, 0], np.zeros((3, 3)), np.zeros(3), g, bias_s[:, 0], _NAN33.copy(),
                    _NAN3.copy(), g_s)


# -- gyro, rate table --------------------------------------------------------------------------

def rate_reference(session: Session, s: StepStats) -> np.ndarray:
    """True mean angular rate (3,) rad/s, body frame, of a rate step over whole revolutions.

    The encoder rate (mean of ``table_rate``; the commanded rate if the column is absent)
    plus the vertical Earth-rate component, about the table's down axis, rotated into the body
    by the mount. The horizontal Earth rate averages out over whole revolutions.
    """
    rate = s.table_rate if np.isfinite(s.table_rate) else s.step.table_rate
    down = rate + earth_rate_ned(session.site.latitude)[2]
    return np.asarray(s.step.mount).T @ np.array([0.0, 0.0, down])


def fit_gyro_rate(session: Session, steps: Sequence[int] | None = None,
                  position_sigma: float | str = 0.0) -> TriadFit:
    """Gyro ``M``, nonlinearity and asymmetry from rate steps (rad/s, body frame).

    Each rate step is reduced to its mean over whole revolutions and compared with
    :func:`rate_reference`. Per axis ``j``: ``y_j = (e_j + M_j) w + asym_j |w_j| + n_j u_j^2 +
    c_j(mount)``, with one offset per mount (bias + G f). Nonlinearity and asymmetry need the
    pair sums ``c + asym r + n r^2`` at three or more rates; with fewer they are dropped and a
    warning says so. Bias and ``G`` are solved from the offsets when the mounts observe them.

    ``position_sigma`` (rad): 1-sigma tilt of the table axis in the body at each step (fixture
    repeatability); it adds ``|w|^2 s^2 (1 - u_j^2)`` to the variance of row ``j`` (the
    off-axis rate it leaks), ``"auto"`` estimates it as :func:`fit_accel` does.
    """
    check_site(session)
    context = f"{session.name}: gyro rate fit"
    recs = session.steps_of_kind("rate") if steps is None else [session.step(i) for i in steps]
    bad = [r for r in recs if r.kind != "rate"]
    if bad:
        raise AnalysisError(f"{context}: {step_name(bad[0])} is a {bad[0].kind} step, not a rate step")
    if not recs:
        raise AnalysisError(f"{context}: the session has no rate steps")
    stats = [whole_revolutions(session, r) for r in recs]
    warnings = []
    if not all(np.isfinite(s.table_rate) for s in stats):
        warnings.append(f"{context}: samples have no table_rate column: the commanded rate is the reference")
    w = np.array([rate_reference(session, s) for s in stats])
    w_nominal = np.array([np.asarray(s.step.mount).T @ np.array([0.0, 0.0, s.step.table_rate]) for s in stats])
    y = np.array([s.gyro for s in stats])
    noise = mean_variance([_rate_error_signal(session, s.step) for s in stats], session.sample_rate_hz)
    var = noise.variance
    mounts = list(dict.fromkeys(_mount_key(s.step.mount) for s in stats))
    onehot = np.array([[float(_mount_key(s.step.mount) == m) for m in mounts] for s in stats])

    speed2 = np.sum(w**2, axis=1)[:, None]
    u2 = w**2 / speed2

    def position_var(sig: float) -> np.ndarray:
        return var + speed2 * sig**2 * (1 - u2) + speed2 * sig**4 * u2

    def build(rows: np.ndarray, sig: float | None = None) -> _AxisFit:
        wr, oh = w[rows], onehot[rows]
        vr = position_var(tilt if sig is None else sig)[rows]
        base = [[f"m{k}" for k in range(3)] + ["asym", "n"] + [f"c{m}" for m in range(len(mounts))]
                for _ in range(3)]
        # observability from the commanded rates (the Earth rate and encoder noise would make a
        # structurally unobservable column look observable at a condition number of ~1e4)
        wn = w_nominal[rows]
        designs = [np.column_stack([wn, np.abs(wn[:, j]), wn[:, j] ** 2, oh]) for j in range(3)]
        keep, dropped = _drop_unobservable(designs, base, vr, droppable=("n", "asym"), context=context)
        names = [[base[j][k] for k in keep[j]] for j in range(3)]

        def model(j, beta):
            p = dict(zip(names[j], beta))
            a = np.eye(3)[j] + np.array([p.get(f"m{k}", 0.0) for k in range(3)])
            u = wr @ a
            nl = p.get("n", 0.0)
            cols = {f"m{k}": wr[:, k] * (1 + 2 * nl * u) for k in range(3)}
            cols.update({"asym": np.abs(wr[:, j]), "n": u**2})
            cols.update({f"c{m}": oh[:, m] for m in range(len(mounts))})
            h = u + nl * u**2 + p.get("asym", 0.0) * np.abs(wr[:, j]) + oh @ np.array(
                [p.get(f"c{m}", 0.0) for m in range(len(mounts))])
            return h, np.column_stack([cols[nm] for nm in names[j]])

        fit = _gauss_newton(model, [np.zeros(len(n)) for n in names], names, y[rows], vr)
        fit.dropped = dropped
        return fit

    def residual_of(fit):
        return lambda i: f"{units.fmt(np.abs(y[i] - w[i]).max(), 'deg/s', 3)} before compensation"

    tilt = _position_sigma(build, position_sigma, len(stats), context)
    fit, used, outliers, w2 = _fit_with_misfits(build, stats, y, position_var(tilt), context, residual_of)
    warnings += w2
    unobserved = sorted({d for d in fit.dropped if not d.startswith("c")})
    if unobserved:
        warnings.append(f"{context}: not observable from these rates (need 3 or more distinct rates): "
                        f"{', '.join('nonlinearity' if d == 'n' else 'asymmetry' for d in unobserved)}")
    m, m_s = _sigma_matrix(fit, "m", 3)
    n, n_s = _sigma_matrix(fit, "n", 1)
    asym, asym_s = _sigma_matrix(fit, "asym", 1)
    offsets, off_cov = _offsets(fit, len(mounts))
    f_m = np.array([np.reshape(k, (3, 3)).T @ np.array([0.0, 0.0, -session.site.gravity]) for k in mounts])
    bias, bias_s, g, g_s = _bias_from_offsets(offsets, off_cov, f_m)
    bias_s = np.sqrt(bias_s**2 + bias_wander(noise, between_step_variance(fit, position_var(tilt)[used])))
    result = TriadFit("gyro", bias, m, n[:, 0], g, bias_s, m_s, n_s[:, 0], g_s, asym[:, 0], asym_s[:, 0])
    off_rows = onehot @ offsets
    comp = TriadModel(np.zeros(3), m, n[:, 0]).compensate(y - off_rows - asym[:, 0] * np.abs(w))
    notes = {"rates_rad_s": sorted({round(float(abs(np.linalg.norm(x))), 9) for x in w}),
             "mount_offsets": offsets.tolist(), "step_offsets": off_rows.tolist(),
             "revolutions": [s.revolutions for s in stats]}
    if np.isnan(bias_s).all():
        notes["bias"] = "not observed: the rate steps' mounts cannot separate bias from g-sensitivity"
    notes.update({"position_sigma_rad": tilt, **_noise_notes(noise)})
    return replace(result, residuals=_residual_frame(stats, w, y, comp, position_var(tilt) * fit.scale, used),
                        outliers=tuple(stats[i].step.index for i in outliers), warnings=tuple(warnings),
                        chi2_reduced=fit.chi2 / fit.dof if fit.dof else float("nan"), dof=fit.dof, notes=notes)


def _rate_error_signal(session: Session, step: StepRecord) -> np.ndarray:
    """Gyro minus the true rate (N, 3), rad/s, over a rate step's whole revolutions (for its noise).

    True rate: encoder rate about the table axis plus the Earth rate (the horizontal part
    rotating with the table when the azimuth is known; else only its vertical part).
    """
    df, _ = whole_revolution_samples(session, step)
    mount = np.asarray(step.mount)
    rate = df["table_rate"].to_numpy(float) if "table_rate" in df.columns else np.full(len(df), step.table_rate)
    w = rate[:, None] * mount.T[:, 2][None, :]
    w_ie = earth_rate_ned(session.site.latitude)
    if session.site.table_zero_azimuth is not None and "table_angle" in df.columns:
        angle = df["table_angle"].to_numpy(float)
        w = w + session.attitude(step, angle[:, None]).inv().apply(w_ie)
    else:
        w = w + w_ie[2] * mount.T[:, 2][None, :]
    return df[["gx", "gy", "gz"]].to_numpy(float) - w


def _offsets(fit: _AxisFit, n_mounts: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """Mount offsets (n_mounts, 3) and, per axis, their covariance (n_mounts, n_mounts)."""
    off = np.zeros((n_mounts, 3))
    covs = []
    for j in range(3):
        idx = [fit.names[j].index(f"c{m}") for m in range(n_mounts)]
        off[:, j] = fit.beta[j][idx]
        covs.append(fit.cov[j][np.ix_(idx, idx)])
    return off, covs


def _bias_from_offsets(off: np.ndarray, covs: list[np.ndarray], f_m: np.ndarray):
    """Bias and G (with sigmas) from per-mount offsets ``c = b + G f``; NaN sigmas if not observable."""
    x = np.column_stack([np.ones(len(f_m)), f_m])
    if len(f_m) < 4 or np.linalg.matrix_rank(x / np.linalg.norm(x, axis=0)) < 4:
        return np.zeros(3), _NAN3.copy(), np.zeros((3, 3)), _NAN33.copy()
    pinv = np.linalg.pinv(x)
    bias, bias_s, g, g_s = np.zeros(3), np.zeros(3), np.zeros((3, 3)), np.zeros((3, 3))
    for j in range(3):
        beta = pinv @ off[:, j]
        cov = pinv @ covs[j] @ pinv.T
        bias[j], bias_s[j] = beta[0], np.sqrt(cov[0, 0])
        g[j], g_s[j] = beta[1:], np.sqrt(np.diag(cov)[1:])
    return bias, bias_s, g, g_s
