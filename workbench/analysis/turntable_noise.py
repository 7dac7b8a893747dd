"""Noise floor of the static turntable fits: between-step variance, bias wander, hidden bias instability.

:func:`between_step_variance` (random-effects variance of the step means beyond their own noise),
:func:`bias_wander` (the Allan bias instability B as a floor, flicker constant of IEEE Std 952),
:func:`hidden_bias_instability` / :func:`hidden_floor_warning` (what short dwells cannot show).
Part of :mod:`workbench.analysis.turntable`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.optimize import brentq
from scipy.special import chdtri  # chi-squared upper quantile: scipy.stats.chi2.isf without importing scipy.stats

from workbench import units
from workbench.allan_model import FLICKER_AVAR
from workbench.analysis.position_check import MeanNoise, StepStats, static_mean_variance
from workbench.analysis.turntable_fit import AXES, POOL_DOF, TriadFit, _AxisFit
from workbench.errors import AnalysisError
from workbench.session import Session


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
    if fit0.dof == 0 or fit0.chi2 <= chdtri(fit0.dof, 1e-3):
        return 0.0

    def excess(log_sig: float) -> float:
        fit = build(np.ones(n, bool), float(np.exp(log_sig)))
        return fit.chi2 / fit.dof - 1.0

    return float(np.exp(brentq(excess, np.log(1e-7), np.log(0.3), xtol=1e-4)))
