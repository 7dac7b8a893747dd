"""Turntable fit machinery shared by the accelerometer and gyro fits: the result type and the solver.

:class:`TriadFit` (estimates, sigmas, residual table, warnings; ``to_dict``, ``summary``, ``to_calibration``),
:func:`check_site`, the Gauss-Newton least squares with unobservable columns dropped, the
misfit test that leaves out positions beyond the noise, the residual table. Constants
:data:`AXES`, :data:`STATIC_KINDS`, :data:`MISFIT_P`, :data:`POOL_DOF`. Part of
:mod:`workbench.analysis.turntable`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.special import chdtri  # chi-squared upper quantile: scipy.stats.chi2.isf without importing scipy.stats

from workbench.analysis.position_check import (
    StepStats, deleted_residual_statistics, motion_in_static, step_name, step_stats,
)
from workbench.calset import CalibrationSet, TriadCalibration
from workbench.errors import AnalysisError
from workbench.json_values import json_value
from workbench.model import TriadModel
from workbench.session import Session


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

    def triad_calibration(self) -> TriadCalibration:
        """A :class:`workbench.calset.TriadCalibration` with the 1-sigma uncertainties."""
        sigma = {"bias": self.bias_sigma, "scale_misalignment": self.scale_misalignment_sigma,
                 "nonlinearity": self.nonlinearity_sigma}
        if self.g_sensitivity is not None:
            sigma["g_sensitivity"] = self.g_sensitivity_sigma
        return TriadCalibration(self.model(), sigma)

    def to_calibration(self, unit=None) -> TriadCalibration | CalibrationSet:
        """The partial calibration set of ``unit`` (a :class:`workbench.calset.Unit`) holding this triad;
        without a unit, the :class:`~workbench.calset.TriadCalibration` alone (:meth:`triad_calibration`)."""
        if unit is None:
            return self.triad_calibration()
        return CalibrationSet(unit=unit, triads={self.triad: self.triad_calibration()})

    def summary(self, full_scale: float | None = None) -> list[str]:
        """Lines for people in lab units (:func:`workbench.analysis.turntable_summary.triad_summary`);
        ``full_scale`` rad/s adds the residual as a percentage of it (a rate table)."""
        from workbench.analysis.turntable_summary import triad_summary

        return triad_summary(self, full_scale)

    def to_dict(self) -> dict:
        """JSON-ready summary (SI, NaN -> None), without the residual table."""
        out = {"triad": self.triad}
        for name in ("bias", "scale_misalignment", "nonlinearity", "g_sensitivity", "asymmetry"):
            out[name] = json_value(getattr(self, name))
            out[name + "_sigma"] = json_value(getattr(self, name + "_sigma"))
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
    limit = chdtri(3, MISFIT_P / n)
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
