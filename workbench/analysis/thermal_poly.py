"""Thermal polynomials: per-axis fits in ``(T - t_ref)`` with a cross-validated order and a hysteresis term.

:func:`fit_thermal_poly` -> :class:`PolyFit` (leave one temperature out, the one-standard-error
rule of Hastie et al. ESL sec. 7.10, never above the lowest order whose held-out errors the
points' sigmas explain; the direction term ``h * s``, ``s = +-1/2`` on rising and
falling branches). :data:`MAX_ORDER`. Part of :mod:`workbench.analysis.thermal`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from workbench.analysis.chi2 import chi2_ppf
from workbench.errors import AnalysisError
from workbench.json_values import json_value as _nan_none


MAX_ORDER = 5


_DT_SCALE = 50.0  # °C, conditioning of the Vandermonde columns (coefficients rescaled back)


# polynomial fits with cross-validated order and a hysteresis (direction) term
@dataclass(frozen=True)
class PolyFit:
    """Per-axis temperature polynomial of one quantity (e.g. gyro bias), SI units.

    ``coeffs`` (3, K): column k multiplies ``(T - t_ref_c)^k`` (lowest power first), padded
    with zeros above each axis's own order ``orders[axis]``; ``coeffs_sigma`` 1-sigma, NaN
    where the coefficient is a padding zero (not estimated). ``hysteresis`` (3,) is the
    up-branch (warming) minus down-branch (cooling) difference (SI), NaN when the data hold one branch only;
    ``hysteresis_modelled`` says where the direction term lowered the held-out residual and
    is part of :meth:`predict`. ``cv_rms[k, axis]`` is the held-out RMS residual of order
    ``cv_orders[k]`` (NaN when too few temperatures), ``cv_rms_chosen`` that of the chosen
    model. The data the fit was made from are kept for figures and residuals.
    """

    quantity: str
    t_ref_c: float
    coeffs: np.ndarray
    coeffs_sigma: np.ndarray
    orders: np.ndarray
    cv_orders: tuple[int, ...]
    cv_rms: np.ndarray
    cv_rms_hysteresis: np.ndarray
    cv_rms_chosen: np.ndarray
    hysteresis: np.ndarray
    hysteresis_sigma: np.ndarray
    hysteresis_modelled: np.ndarray
    temperature_c: np.ndarray
    values: np.ndarray
    sigma: np.ndarray
    direction: np.ndarray
    residuals: np.ndarray
    warnings: tuple[str, ...] = ()

    def predict(self, temperature_c, direction=None) -> np.ndarray:
        """Model value (N, 3) at ``temperature_c`` (N,) °C; ``direction`` (N,) +1 up / -1 down.

        Without ``direction`` (or where it is 0) the mid-branch curve is returned; the
        hysteresis term is added only on axes where it was modelled.
        """
        tc = np.atleast_1d(np.asarray(temperature_c, float))
        dt = tc - self.t_ref_c
        out = np.zeros((tc.size, 3))
        for k in range(self.coeffs.shape[1] - 1, -1, -1):
            out = out * dt[:, None] + self.coeffs[:, k]
        if direction is not None:
            s = 0.5 * np.sign(np.broadcast_to(np.asarray(direction, float), tc.shape))
            h = np.where(self.hysteresis_modelled, np.nan_to_num(self.hysteresis), 0.0)
            out = out + s[:, None] * h
        return out

    @property
    def order(self) -> int:
        """Highest order over the three axes."""
        return int(self.orders.max())

    def to_dict(self) -> dict:
        """JSON-ready summary (SI; ``cv_rms`` indexed [order][axis])."""
        return {
            "quantity": self.quantity, "t_ref_c": self.t_ref_c, "orders": self.orders.tolist(),
            "coeffs": self.coeffs.tolist(), "coeffs_sigma": _nan_none(self.coeffs_sigma),
            "cv_orders": list(self.cv_orders), "cv_rms": _nan_none(self.cv_rms),
            "cv_rms_with_hysteresis": _nan_none(self.cv_rms_hysteresis),
            "cv_rms_chosen": _nan_none(self.cv_rms_chosen),
            "hysteresis": _nan_none(self.hysteresis), "hysteresis_sigma": _nan_none(self.hysteresis_sigma),
            "hysteresis_modelled": self.hysteresis_modelled.tolist(),
            "residual_rms": _nan_none(np.sqrt(np.nanmean(self.residuals**2, axis=0))),
            "n_points": int(len(self.temperature_c)),
            "n_temperatures": int(len(np.unique(np.round(self.temperature_c, 1)))),
        }


def _design(dt: np.ndarray, order: int, s: np.ndarray | None) -> np.ndarray:
    cols = (dt / _DT_SCALE)[:, None] ** np.arange(order + 1)
    return np.column_stack([cols, s]) if s is not None else cols


def _wls(a: np.ndarray, y: np.ndarray, w: np.ndarray | None):
    """Weighted least squares; returns (params, covariance).

    With weights ``w = 1 / sigma^2`` the covariance ``(A' W A)^-1`` is scaled by the Birge
    ratio ``max(1, chi2 / dof)`` (scatter the sigmas do not explain widens it); without
    weights (None) by the residual variance ``RSS / dof``.
    """
    ww = np.ones(len(y)) if w is None else w
    sw = np.sqrt(ww)
    p, *_ = np.linalg.lstsq(a * sw[:, None], y * sw, rcond=None)
    r = (y - a @ p) * sw
    dof = len(y) - a.shape[1]
    var = float(r @ r) / dof if dof > 0 else np.nan
    try:
        cov = np.linalg.inv((a * ww[:, None]).T @ a)
    except np.linalg.LinAlgError:
        cov = np.full((a.shape[1], a.shape[1]), np.nan)
    factor = var if w is None else (max(1.0, var) if np.isfinite(var) else np.nan)
    return p, cov * factor


def _cv_errors(dt, y, w, s, groups, order) -> tuple[np.ndarray, np.ndarray] | None:
    """Held-out squared errors per point (leave one group out), or None if infeasible.

    Returns (squared errors, the same divided by their expected value ``sigma^2 + a' (A'WA)^-1 a``
    from the points' own sigmas: 1 on average when the order explains the data to their noise;
    NaN without weights).
    """
    err = np.full(len(y), np.nan)
    z2 = np.full(len(y), np.nan)
    for g in np.unique(groups):
        test = groups == g
        train = ~test
        n_temps = len(np.unique(np.round(dt[train], 3)))
        npar = order + 1 + (s is not None)
        if n_temps < order + 1 or train.sum() < npar:
            return None
        a = _design(dt[train], order, None if s is None else s[train])
        if np.linalg.matrix_rank(a) < a.shape[1]:
            return None
        p, _ = _wls(a, y[train], None if w is None else w[train])
        at = _design(dt[test], order, None if s is None else s[test])
        err[test] = (y[test] - at @ p) ** 2
        if w is not None:
            info = np.linalg.inv((a * w[train][:, None]).T @ a)
            z2[test] = err[test] / (1.0 / w[test] + np.einsum("ij,jk,ik->i", at, info, at))
    return err, z2


def _group_means(err: np.ndarray, groups: np.ndarray) -> np.ndarray:
    return np.array([err[groups == g].mean() for g in np.unique(groups)])


def _one_se(per_group: Mapping) -> int:
    """Lowest order whose mean held-out error is within one standard error of the best order's.

    ``per_group[order]`` holds one held-out mean squared error per cross-validation group. The
    standard error is that of the paired difference to the best order over the groups (the
    orders are compared on the same held-out temperatures, so the spread the groups share
    cancels); the one-standard-error rule of Hastie et al., ESL sec. 7.10.
    """
    mse = {k: v.mean() for k, v in per_group.items()}
    best = min(mse, key=mse.get)

    def se(k) -> float:
        d = per_group[k] - per_group[best]
        return float(d.std(ddof=1) / np.sqrt(len(d))) if len(d) > 1 else 0.0

    return min(k for k in mse if mse[k] <= mse[best] + se(k))


def _select_order(cv: dict, groups: np.ndarray) -> int:
    """Order of one axis by the one-standard-error rule; ``cv[order]`` = held-out squared errors per point."""
    return _one_se({k: _group_means(e, groups) for k, e in cv.items()})


def _select_common_order(cv: list[dict], groups: np.ndarray) -> int:
    """One order for all axes: the one-standard-error rule on the axis-normalised held-out MSE
    (each axis's per-group MSE divided by that axis's best mean, averaged over the axes)."""
    orders = sorted(set.intersection(*(set(c) for c in cv)))
    best = [min(_group_means(e, groups).mean() for e in c.values()) for c in cv]
    return _one_se({k: np.mean([_group_means(c[k], groups) / b for c, b in zip(cv, best)], axis=0) for k in orders})


def _explained_order(z2: dict) -> int | None:
    """Lowest order whose held-out errors the points' own sigmas explain, or None.

    ``z2[order]``: held-out squared errors over their expected value (see :func:`_cv_errors`).
    Explained: their sum within the 95 % point of chi-squared with one degree of freedom per
    point. With few temperatures leave-one-out can favour a high order that happens to run
    through the noise of the others (7 soaks, order 5: each held-out fit interpolates its six
    points); an order whose held-out errors are already at the noise does not need it.
    """
    for k in sorted(z2):
        n = int(np.isfinite(z2[k]).sum())
        if n and np.isfinite(z2[k]).all() and z2[k].sum() <= float(chi2_ppf(0.95, n)):
            return k
    return None


def _simplest(chosen: int, z2: dict) -> int:
    """``chosen`` (the one-standard-error order), or a lower order the noise already explains."""
    explained = _explained_order(z2)
    return chosen if explained is None else min(chosen, explained)


def coefficient_sigma(fit: PolyFit, extra_cov: np.ndarray) -> np.ndarray:
    """1-sigma (3, K) of ``fit``'s coefficients when its points' errors are correlated.

    ``extra_cov`` (3, N, N): covariance each axis's points carry beyond their own sigmas (SI²,
    e.g. a bias random walk between soaks). The estimates are the fit's own weighted least
    squares ``p = G y``, ``G = (A'WA)^-1 A'W``; their covariance under ``diag(sigma^2) +
    extra_cov`` is ``G C G'`` (the sandwich form, the weights left as fitted). NaN where a
    coefficient was not estimated.
    """
    out = np.full(fit.coeffs_sigma.shape, np.nan)
    dt = fit.temperature_c - fit.t_ref_c
    for ax in range(3):
        if not np.isfinite(fit.coeffs_sigma[ax, 0]):
            continue
        k = int(fit.orders[ax])
        a = _design(dt, k, 0.5 * np.sign(fit.direction) if fit.hysteresis_modelled[ax] else None)
        w = 1.0 / fit.sigma[:, ax] ** 2
        g = np.linalg.solve((a * w[:, None]).T @ a, (a * w[:, None]).T)
        cov = g @ (np.diag(fit.sigma[:, ax] ** 2) + extra_cov[ax]) @ g.T
        out[ax, :k + 1] = np.sqrt(np.diag(cov)[:k + 1]) * _DT_SCALE ** -np.arange(k + 1)
    return out


def fit_thermal_poly(temperature_c, values, sigma=None, direction=None, groups=None, t_ref_c: float = 25.0,
                     max_order: int = MAX_ORDER, order: int | None = None, quantity: str = "",
                     hysteresis: str = "auto", per_axis: bool = True) -> PolyFit:
    """Fit per-axis polynomials in ``(T - t_ref_c)`` with a cross-validated order.

    Each axis has its own order (``per_axis``), the lowest whose held-out (leave one
    temperature out) mean squared error is within one standard error of that axis's best,
    or, with ``sigma`` given, a lower one whose held-out errors the sigmas already explain
    (chi-squared, 95 %: :func:`_explained_order`);
    with ``per_axis=False`` the three axes share one order, chosen by the same rule on the
    axis-normalised error (steadier with many temperatures, but one axis's need for a high
    order is then imposed on the others). The held-out RMS of every order is reported per
    axis, with and without the hysteresis term. The direction term is kept on an axis when it lowers that
    axis's held-out RMS ("auto"), always ("on") or never ("off").

    Parameters
    ----------
    temperature_c : (N,) °C, unit temperature of each measurement.
    values : (N, 3) SI (rad/s, m/s^2 or dimensionless scale factor), body axes; NaN on an
        axis that is not observed.
    sigma : (N, 3) 1-sigma of each value (weights), or None (equal weights).
    direction : (N,) +1 on a rising (up) branch, -1 on a falling (down) branch, 0 unknown.
    groups : (N,) cross-validation folds (default: one per distinct temperature, 0.5 °C).
    order : a fixed order instead of the cross-validated choice.

    Raises AnalysisError when the distinct temperatures cannot support the order asked.
    """
    tc = np.asarray(temperature_c, float)
    y = np.asarray(values, float).reshape(len(tc), 3)
    sig = np.ones_like(y) if sigma is None else np.asarray(sigma, float).reshape(y.shape)
    d = np.zeros(len(tc)) if direction is None else np.sign(np.asarray(direction, float))
    groups = np.round(tc * 2) / 2 if groups is None else np.asarray(groups)
    axes = [ax for ax in range(3)
            if np.isfinite(y[:, ax]).all() and (np.isfinite(sig[:, ax]) & (sig[:, ax] > 0)).all()]
    warnings = [f"{quantity}: axis {'xyz'[ax]} not observed at every temperature (not fitted)"
                for ax in range(3) if ax not in axes and np.isfinite(y[:, ax]).any()]
    n_temps = len(np.unique(np.round(tc, 1)))
    if order is not None and n_temps < order + 1:
        raise AnalysisError(f"{quantity}: {n_temps} distinct temperature(s); order {order} needs at least {order + 1}")
    if n_temps < 2:
        raise AnalysisError(f"{quantity}: {n_temps} distinct temperature(s); a temperature model needs at least 2")
    if not axes:
        raise AnalysisError(f"{quantity}: no axis observed at every temperature")
    shared = set(groups[d > 0]) & set(groups[d < 0])
    both = len(shared) >= 2
    if not both and (d > 0).any() and (d < 0).any():
        lone = -1 if (d < 0).sum() <= (d > 0).sum() else 1
        temps = ", ".join(f"{t:.1f}" for t in tc[d == lone])
        warnings.append(f"{quantity}: hysteresis not observable (up and down branches share {len(shared)} "
                        f"temperature(s)); the point(s) at {temps} °C approached from "
                        f"{'above' if lone < 0 else 'below'} may sit half the hysteresis off the fit")
    if hysteresis == "on" and not both:
        warnings.append(f"{quantity}: hysteresis asked but the data hold one branch only")
    top = max(min(max_order, n_temps - 2), 0)
    if order is None and top < min(3, max_order):
        warnings.append(f"{quantity}: only {n_temps} distinct temperatures: orders above {top} cannot be "
                        "cross-validated")
    cv_orders = tuple(range(max(max_order, order or 0) + 1))
    candidates = range(top + 1) if order is None else (order,)
    s_all = 0.5 * d
    dt = tc - t_ref_c
    cv_rms = np.full((len(cv_orders), 3), np.nan)
    cv_rms_h = np.full((len(cv_orders), 3), np.nan)
    weights, cv_sel, z2_sel = {}, [], []
    for ax in axes:
        weights[ax] = None if sigma is None else 1.0 / sig[:, ax] ** 2
        sel, z2 = {}, {}
        for k in candidates:
            e0 = _cv_errors(dt, y[:, ax], weights[ax], None, groups, k)
            eh = _cv_errors(dt, y[:, ax], weights[ax], s_all, groups, k) if both else None
            if e0 is not None:
                cv_rms[k, ax] = np.sqrt(e0[0].mean())
            if eh is not None:
                cv_rms_h[k, ax] = np.sqrt(eh[0].mean())
            pick = eh if (both and hysteresis != "off") else e0
            if pick is not None:
                sel[k], z2[k] = pick
        cv_sel.append(sel)
        z2_sel.append(z2)
    feasible = [k for k in candidates if all(k in c for c in cv_sel)]
    if order is not None:
        axis_order = dict.fromkeys(axes, order)
    elif per_axis:
        axis_order = {ax: _simplest(_select_order(sel, groups), z2) if sel else top
                      for ax, sel, z2 in zip(axes, cv_sel, z2_sel)}
    else:
        common = _select_common_order([{k: c[k] for k in feasible} for c in cv_sel], groups) if feasible else top
        explained = [_explained_order({k: z[k] for k in feasible}) for z in z2_sel]
        if feasible and None not in explained:
            common = min(common, max(explained))
        axis_order = dict.fromkeys(axes, common)
    K = max(axis_order.values()) + 1
    coeffs = np.zeros((3, K))
    coeffs_sigma = np.full((3, K), np.nan)
    orders = np.zeros(3, int)
    h, h_sigma, cv_chosen = np.full(3, np.nan), np.full(3, np.nan), np.full(3, np.nan)
    h_used = np.zeros(3, bool)
    for ax in axes:
        k_sel = axis_order[ax]
        scale = _DT_SCALE ** -np.arange(k_sel + 1)
        if both:  # hysteresis is always reported, from the chosen order with the direction term
            p, cov = _wls(_design(dt, k_sel, s_all), y[:, ax], weights[ax])
            h[ax], h_sigma[ax] = p[-1], np.sqrt(cov[-1, -1])
            h_used[ax] = hysteresis == "on" or (hysteresis == "auto" and cv_rms_h[k_sel, ax] < cv_rms[k_sel, ax])
        p, cov = _wls(_design(dt, k_sel, s_all if h_used[ax] else None), y[:, ax], weights[ax])
        coeffs[ax, :k_sel + 1] = p[:k_sel + 1] * scale
        coeffs_sigma[ax, :k_sel + 1] = np.sqrt(np.diag(cov)[:k_sel + 1]) * scale
        orders[ax] = k_sel
        cv_chosen[ax] = (cv_rms_h if h_used[ax] else cv_rms)[k_sel, ax]
        if np.isfinite(cv_chosen[ax]):
            # the value at t_ref is a prediction like the held-out ones: its 1-sigma is at least
            # their RMS error (the least-squares sigma alone trusts a model of few points)
            coeffs_sigma[ax, 0] = max(coeffs_sigma[ax, 0], cv_chosen[ax])
    fit = PolyFit(quantity, float(t_ref_c), coeffs, coeffs_sigma, orders, cv_orders, cv_rms, cv_rms_h,
                  cv_chosen, h, h_sigma, h_used, tc, y, sig, d, np.full_like(y, np.nan), tuple(warnings))
    object.__setattr__(fit, "residuals", y - fit.predict(tc, d))
    return fit
