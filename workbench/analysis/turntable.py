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

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from workbench import units
from workbench.analysis.turntable_fit import (  # noqa: F401
    AXES, MISFIT_P, POOL_DOF, STATIC_KINDS, TriadFit, _AxisFit, _NAN3, _NAN33, _angle, _drop_unobservable,
    _fit_with_misfits, _gauss_newton, _residual_frame, _sigma_matrix, _specific_force, _static_stats,
    check_site,
)
from workbench.analysis.turntable_noise import (  # noqa: F401
    _hidden_floor, _noise_notes, _position_sigma, _static_noise, _with_bias_wander, between_step_variance,
    bias_wander, hidden_bias_instability, hidden_floor_warning,
)
from workbench.analysis.turntable_rate import fit_gyro_rate, rate_reference  # noqa: F401
from workbench.earth import EARTH_RATE, earth_rate_ned
from workbench.errors import AnalysisError
from workbench.session import Session


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
