"""Thermal sweeps: bias and scale factor against the unit's own temperature.

Three layers, each usable on its own:

* :func:`settling` finds when the unit temperature stops moving (a sliding-window slope,
  °C/min, below a tolerance until the end of the record).
* :func:`fit_thermal_poly` fits per-axis polynomials in ``(T - t_ref)`` to values measured at
  temperatures ``T`` (soak means or ramp windows), chooses the order by cross-validation
  (leave one temperature out; the smallest order whose held-out mean squared error is within
  one standard error of the best, Hastie et al. ESL sec. 7.10) and estimates the up/down
  hysteresis as a direction term ``h * s`` with ``s = +1/2`` on a rising (up) branch and
  ``-1/2`` on a falling (down) branch, i.e. a term in ``sign(dT/dt)``; ``h`` is the
  warming-minus-cooling difference at the same temperature. The term is kept in the
  model only when it lowers the held-out residual; it is always reported.
* :func:`soak_points` / :func:`ramp_series` turn a session into those measurements, re-using
  the turntable estimators (``workbench.analysis.turntable``) at each soak, and
  :func:`analyze_thermal` ties them together into a :class:`ThermalResult`, which becomes the
  ``thermal`` block of a calibration set (:func:`to_calibration`).

Model (``workbench/model.py``): ``b(T) = bias + sum_k bias_poly[:, k] (T - t_ref)^k`` and
``M(T) = M + diag(sum_k scale_poly[:, k] (T - t_ref)^k)``. The fitted constant terms go into
``bias`` and ``diag(M)``, so ``bias_poly[:, 0] = scale_poly[:, 0] = 0``.

References: thesis (shared/seeds/000_...) sec. 1.3 (thermal tests in a climatic chamber to
compensate bias and scale-factor temperature dependence; hysteresis named among the error
sources in sec. 1.2).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from workbench.errors import AnalysisError, SessionError

MAX_ORDER = 5
QUANTITIES = ("gyro.bias", "gyro.scale", "accel.bias", "accel.scale")
_DT_SCALE = 50.0  # °C, conditioning of the Vandermonde columns (coefficients rescaled back)


# ---------------------------------------------------------------------------------------
# settling
@dataclass(frozen=True)
class Settling:
    """Whether and when the unit temperature settled during one record.

    ``t_settled`` (s, session time) is the first time after which the windowed slope stays
    below the tolerance (None when it never does); ``final_rate_c_per_min`` is the slope over
    the last window, °C/min.
    """

    settled: bool
    t_settled: float | None
    final_rate_c_per_min: float
    tol_c_per_min: float


def _binned(t: np.ndarray, y: np.ndarray, bin_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Mean of ``y`` in consecutive bins of ``bin_s`` seconds (cheap decimation)."""
    idx = np.floor((t - t[0]) / bin_s).astype(int)
    counts = np.bincount(idx)
    keep = counts > 0
    tb = np.bincount(idx, t)[keep] / counts[keep]
    yb = np.bincount(idx, y)[keep] / counts[keep]
    return tb, yb


def windowed_slope(t: np.ndarray, temp_c: np.ndarray, window_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares slope of ``temp_c`` over the trailing ``window_s`` at each 1/10-window bin.

    Returns (bin times s, slope °C/s); NaN where the window is not yet full.
    """
    tb, yb = _binned(np.asarray(t, float), np.asarray(temp_c, float), window_s / 10.0)
    n = len(tb)
    slope = np.full(n, np.nan)
    if n < 3:
        return tb, slope
    x = tb - tb[0]
    c = [np.concatenate([[0.0], np.cumsum(v)]) for v in (np.ones(n), x, yb, x * x, x * yb)]
    start = np.searchsorted(tb, tb - window_s * (1 - 1e-9))
    end = np.arange(1, n + 1)
    s0, sx, sy, sxx, sxy = (ci[end] - ci[start] for ci in c)
    den = s0 * sxx - sx * sx
    full = (tb - tb[start] >= 0.8 * window_s) & (den > 0)
    slope[full] = (s0 * sxy - sx * sy)[full] / den[full]
    return tb, slope


def settling(t: np.ndarray, temp_c: np.ndarray, tol_c_per_min: float = 0.05,
             window_s: float = 120.0) -> Settling:
    """Detect settling of the unit temperature ``temp_c`` (°C) sampled at times ``t`` (s).

    The slope is fitted over a trailing window of ``window_s``; the record is settled from the
    first time after which ``|slope|`` stays below ``tol_c_per_min`` to the end.
    """
    t = np.asarray(t, float)
    if len(t) < 2 or t[-1] - t[0] < window_s:
        window_s = max((t[-1] - t[0]) if len(t) > 1 else 0.0, 1e-9)
    tb, slope = windowed_slope(t, temp_c, window_s)
    rate = np.abs(slope) * 60.0
    valid = np.isfinite(rate)
    if not valid.any():
        return Settling(False, None, float("nan"), tol_c_per_min)
    final = float(slope[valid][-1] * 60.0)
    bad = valid & (rate >= tol_c_per_min)
    if bad[valid][-1]:
        return Settling(False, None, final, tol_c_per_min)
    last_bad = np.flatnonzero(bad)
    first_ok = int(last_bad[-1] + 1) if last_bad.size else int(np.flatnonzero(valid)[0])
    return Settling(True, float(tb[first_ok]), final, tol_c_per_min)


# ---------------------------------------------------------------------------------------
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


def _nan_none(a):
    a = np.asarray(a, float)
    if a.ndim == 0:
        return None if not np.isfinite(a) else float(a)
    return [_nan_none(x) for x in a]


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


def _cv_errors(dt, y, w, s, groups, order) -> np.ndarray | None:
    """Held-out squared errors per point (leave one group out), or None if infeasible."""
    err = np.full(len(y), np.nan)
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
    return err


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


def fit_thermal_poly(temperature_c, values, sigma=None, direction=None, groups=None, t_ref_c: float = 25.0,
                     max_order: int = MAX_ORDER, order: int | None = None, quantity: str = "",
                     hysteresis: str = "auto", per_axis: bool = True) -> PolyFit:
    """Fit per-axis polynomials in ``(T - t_ref_c)`` with a cross-validated order.

    Each axis has its own order (``per_axis``), the lowest whose held-out (leave one
    temperature out) mean squared error is within one standard error of that axis's best;
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
    weights, cv_sel = {}, []
    for ax in axes:
        weights[ax] = None if sigma is None else 1.0 / sig[:, ax] ** 2
        sel = {}
        for k in candidates:
            e0 = _cv_errors(dt, y[:, ax], weights[ax], None, groups, k)
            eh = _cv_errors(dt, y[:, ax], weights[ax], s_all, groups, k) if both else None
            if e0 is not None:
                cv_rms[k, ax] = np.sqrt(e0.mean())
            if eh is not None:
                cv_rms_h[k, ax] = np.sqrt(eh.mean())
            pick = eh if (both and hysteresis != "off") else e0
            if pick is not None:
                sel[k] = pick
        cv_sel.append(sel)
    feasible = [k for k in candidates if all(k in c for c in cv_sel)]
    if order is not None:
        axis_order = dict.fromkeys(axes, order)
    elif per_axis:
        axis_order = {ax: _select_order(sel, groups) if sel else top for ax, sel in zip(axes, cv_sel)}
    else:
        common = _select_common_order([{k: c[k] for k in feasible} for c in cv_sel], groups) if feasible else top
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


# ---------------------------------------------------------------------------------------
# from a session: soak points and ramp windows
@dataclass(frozen=True)
class SoakPoint:
    """Estimates of one triad at one soak (SI; ``scale`` = diag of M, NaN where not observed).

    ``temperature_c`` is the mean unit temperature over the measurement steps and
    ``rate_c_per_min`` its slope there; ``settle_time_s`` the time the soak step took to settle
    (None when it never did); ``settled`` = ``|rate_c_per_min|`` below the tolerance.

    ``elapsed_s`` the mean time of the measurement steps since the session started (the bias
    random walk since power-on grows with it, :func:`with_bias_random_walk`).

    ``direction`` +1 when the unit approached this temperature from below (up branch),
    -1 from above (down branch), 0 when it did not move (first soak at ambient).
    """

    triad: str
    soak_step: int
    steps: tuple[int, ...]
    setpoint_c: float | None
    temperature_c: float
    rate_c_per_min: float
    settle_time_s: float | None
    direction: int
    bias: np.ndarray
    bias_sigma: np.ndarray
    scale: np.ndarray
    scale_sigma: np.ndarray
    settled: bool
    elapsed_s: float = float("nan")  # mean time of the measurement steps since the session's first sample


@dataclass(frozen=True)
class SoakGroup:
    """A soak step and the measurement steps that follow it at the same setpoint."""

    soak_step: int
    setpoint_c: float | None
    steps: tuple[int, ...]


def _require_temp(session, steps) -> None:
    if "temp" not in session.samples.columns:
        where = f"step(s) {', '.join(str(s) for s in steps)}" if steps else "all steps"
        raise SessionError(f"{session.name}: column temp (unit temperature, °C) is missing; "
                           f"a thermal analysis needs it ({where})")


def soak_groups(session) -> list[SoakGroup]:
    """Group the session's steps: each ``soak`` step with the non-soak, non-ramp steps after it."""
    groups: list[SoakGroup] = []
    for st in sorted(session.steps, key=lambda s: s.t_start):
        if st.kind == "soak":
            groups.append(SoakGroup(st.index, st.temperature_c, ()))
        elif st.kind == "ramp":
            groups.append(SoakGroup(-1, None, ()))  # a ramp ends the current soak group
        elif groups and groups[-1].soak_step >= 0:
            g = groups[-1]
            groups[-1] = SoakGroup(g.soak_step, g.setpoint_c, (*g.steps, st.index))
    return [g for g in groups if g.steps]


def _samples_of(session, steps) -> np.ndarray:
    return np.isin(session.samples["step"].to_numpy(), list(steps))


def _turntable():
    try:
        from workbench.analysis import turntable
    except ImportError as exc:  # written concurrently; the soak analysis needs it
        raise AnalysisError(f"soak analysis needs workbench.analysis.turntable ({exc})") from None
    return turntable


def soak_points(session, triads=("gyro", "accel"), settle_tol_c_per_min: float = 0.05,
                settle_window_s: float = 120.0, position_sigma: float | str = 0.0,
                bias_instability: Mapping[str, np.ndarray | None] | None = None
                ) -> tuple[dict[str, list[SoakPoint]], list[str]]:
    """Per-soak bias and scale factor of each triad, from the turntable estimators.

    For each soak group the accelerometer is fitted with ``fit_accel`` on the group's static
    steps; the gyro bias with ``fit_gyro_static`` on the same steps and, when the group has
    rate steps, the gyro scale factor with ``fit_gyro_rate`` (else not observed, NaN). The
    ``position_sigma`` (rad, or ``"auto"``) is the fixture's 1-sigma repeatability passed to the
    turntable estimators; ``bias_instability`` maps a triad to its Allan bias instability B (SI,
    scalar or (3,)), the floor of each soak's bias sigma (``turntable.fit_accel``). The soak's temperature is the mean unit temperature over its
    measurement steps; a soak whose
    unit temperature still moves
    during the measurement steps (regression slope at or above ``settle_tol_c_per_min``) is
    reported in the warnings naming the step and flagged ``settled=False`` (left out of the
    fits); the soak step's own settling time (:func:`settling`) is kept for the report.
    Returns ({triad: [SoakPoint]}, warnings).
    """
    tt = _turntable()
    groups = soak_groups(session)
    if not groups:
        raise SessionError(f"{session.name}: no soak step followed by measurement steps")
    _require_temp(session, [g.soak_step for g in groups])
    t_all = session.samples["t"].to_numpy(float)
    temp_all = session.samples["temp"].to_numpy(float)
    out: dict[str, list[SoakPoint]] = {t: [] for t in triads}
    warnings: list[str] = []
    hidden: dict[str, list] = {t: [] for t in triads}  # per soak: step, hideable bias instability (3,), dwell s
    prev_temp = None
    for g in groups:
        soak_sel = _samples_of(session, [g.soak_step])
        meas_sel = _samples_of(session, g.steps)
        ts, temps = t_all[soak_sel], temp_all[soak_sel]
        tm, tempm = t_all[meas_sel], temp_all[meas_sel]
        st = settling(ts, temps, settle_tol_c_per_min, settle_window_s) if len(ts) > 2 else None
        settle_time = None if st is None or not st.settled else st.t_settled - ts[0]
        rate_se = 0.0
        if len(tm) > 3 and tm[-1] - tm[0] >= 10.0:
            p, cov = np.polyfit(tm - tm[0], tempm, 1, cov=True)
            rate, rate_se = float(p[0] * 60.0), float(np.sqrt(cov[0, 0]) * 60.0)
        else:  # measurement too short to tell: the soak's own final slope
            rate = st.final_rate_c_per_min if st is not None else 0.0
        # unsettled only when the slope exceeds the tolerance by more than its 2-sigma
        # (the unit's thermometer noise makes a short regression slope uncertain)
        settled = abs(rate) - 2.0 * rate_se < settle_tol_c_per_min
        if not settled:
            how = "never settled" if settle_time is None else f"settled after {settle_time:.0f} s"
            warnings.append(f"step {g.soak_step} (soak {g.setpoint_c} °C): unit temperature did not settle: "
                            f"{rate:.3g} ± {rate_se:.2g} °C/min over measurement steps {g.steps[0]}-{g.steps[-1]} (tolerance "
                            f"{settle_tol_c_per_min} °C/min; soak step {how}); soak left out of the fit")
        mean_t = float(tempm.mean())
        start_t = float(temps[0]) if len(temps) else mean_t
        ref = prev_temp if prev_temp is not None else start_t
        move = mean_t - ref
        direction = 0 if abs(move) < 0.5 else (1 if move > 0 else -1)
        prev_temp = mean_t
        statics = [i for i in g.steps if session.step(i).kind == "static"]
        rates = [i for i in g.steps if session.step(i).kind == "rate"]
        for triad in triads:
            if triad == "accel":
                fit = tt.fit_accel(session, steps=statics, position_sigma=position_sigma,
                                   bias_instability=(bias_instability or {}).get("accel"), warn_hidden_floor=False)
                bias, bias_s = fit.bias, fit.bias_sigma
                scale, scale_s = np.diag(fit.scale_misalignment), np.diag(fit.scale_misalignment_sigma)
            else:
                rfit = tt.fit_gyro_rate(session, steps=rates, position_sigma=position_sigma) if rates else None
                m = None if rfit is None else np.where(np.isfinite(rfit.scale_misalignment_sigma),
                                                       rfit.scale_misalignment, 0.0)
                fit = tt.fit_gyro_static(session, steps=statics, scale_misalignment=m,
                                         bias_instability=(bias_instability or {}).get("gyro"),
                                         warn_hidden_floor=False)
                bias, bias_s = fit.bias, fit.bias_sigma
                scale = np.full(3, np.nan) if rfit is None else np.diag(rfit.scale_misalignment)
                scale_s = np.full(3, np.nan) if rfit is None else np.diag(rfit.scale_misalignment_sigma)
            warnings += [f"soak step {g.soak_step}: {w}" for w in fit.warnings]
            hidden[triad].append((g.soak_step, np.array(fit.notes["hidden_bias_instability"], float),
                                  min(session.step(i).duration for i in statics)))
            out[triad].append(SoakPoint(triad, g.soak_step, g.steps, g.setpoint_c, mean_t, rate, settle_time,
                                        direction,
                                        np.asarray(bias, float), np.asarray(bias_s, float),
                                        np.asarray(scale, float).copy(), np.asarray(scale_s, float).copy(), settled,
                                        float(tm.mean() - t_all[0])))
    # the first soak (usually at ambient) takes the direction of the next one's approach
    for pts in out.values():
        for i, p in enumerate(pts):
            if p.direction == 0 and i + 1 < len(pts) and pts[i + 1].direction != 0:
                pts[i] = replace(p, direction=pts[i + 1].direction)
    # one warning per triad for the soaks whose dwells could hide a bias instability (largest per axis)
    for triad, per_soak in hidden.items():
        steps = [step for step, b, _ in per_soak if np.isfinite(b).any()]
        if steps:
            with np.errstate(all="ignore"):
                worst = np.nanmax(np.array([b for _, b, _ in per_soak]), axis=0)
            what = "accelerometer fit" if triad == "accel" else "gyro static fit"
            warnings += tt.hidden_floor_warning(worst, None, min(d for _, _, d in per_soak),
                                                "mg" if triad == "accel" else "deg/h",
                                                f"soak steps {', '.join(map(str, steps))}: {what}")
    return out, warnings


@dataclass(frozen=True)
class RampSeries:
    """Windowed means over ramp steps: unit temperature, its rate and the triad's bias.

    ``bias`` (N, 3) SI = mean output minus ``(I + M_ref)`` times the known input (Earth rate or
    gravity in the body frame); ``direction`` +1 rising, -1 falling; ``steps`` the ramp step of
    each window; ``elapsed_s`` the window's mean time since the session's first sample.
    """

    triad: str
    temperature_c: np.ndarray
    rate_c_per_min: np.ndarray
    bias: np.ndarray
    bias_sigma: np.ndarray
    direction: np.ndarray
    steps: np.ndarray
    elapsed_s: np.ndarray


def _ramp_runs(ramps) -> list[list]:
    """Consecutive ramp steps that belong to one chamber ramp (same target and rate)."""
    runs: list[list] = []
    for st in ramps:
        key = (st.extra.get("ramp_to_c"), st.extra.get("ramp_rate_c_per_min"))
        if runs and (runs[-1][0].extra.get("ramp_to_c"), runs[-1][0].extra.get("ramp_rate_c_per_min")) == key:
            runs[-1].append(st)
        else:
            runs.append([st])
    return runs


def _ramp_lag_warnings(session, ramps, lag_tolerance: float) -> list[str]:
    """Warnings for ramps whose unit temperature rate falls short of the commanded rate."""
    out = []
    for run in _ramp_runs(ramps):
        commanded = run[0].extra.get("ramp_rate_c_per_min")
        sel = _samples_of(session, [s.index for s in run])
        t = session.samples["t"].to_numpy(float)[sel]
        temp = session.samples["temp"].to_numpy(float)[sel]
        if commanded is None or len(t) < 3:
            continue
        measured = (temp[-1] - temp[0]) / (t[-1] - t[0]) * 60.0
        if abs(measured) < (1.0 - lag_tolerance) * abs(float(commanded)):
            names = f"{run[0].index}" if len(run) == 1 else f"{run[0].index}-{run[-1].index}"
            out.append(f"step {names} (ramp to {run[0].extra.get('ramp_to_c')} °C): unit temperature moved at "
                       f"{measured:.3g} °C/min for a commanded {float(commanded):.3g} °C/min: ramp too fast for "
                       "the unit's thermal lag (bias is then fitted against a temperature that is not the "
                       "sensor's own)")
    return out


def ramp_series(session, triad: str, window_s: float = 60.0, reference=None,
                lag_tolerance: float = 0.2) -> tuple[RampSeries, list[str]]:
    """Bias of ``triad`` against the unit temperature over the session's ``ramp`` steps.

    ``reference`` is a TriadModel (e.g. from a turntable calibration) whose ``I + M`` maps the
    known input (Earth rate in the body frame for the gyro, specific force for the
    accelerometer) to the output and whose gyro ``G`` removes the g-sensitivity ``G f``;
    None = identity and no ``G`` (the gyro "bias" then includes ``G f`` of the position).
    For an accelerometer held in one position the bias of an axis along gravity absorbs the
    scale-factor change times g (a warning says so). A ramp whose unit temperature rate falls
    short of the commanded rate by more than ``lag_tolerance`` (fraction), i.e. too fast for
    the unit's thermal lag, is reported in the warnings naming the step.
    """
    from workbench.earth import earth_rate_ned

    ramps = sorted(session.steps_of_kind("ramp"), key=lambda s: s.t_start)
    if not ramps:
        raise SessionError(f"{session.name}: no ramp step")
    _require_temp(session, [s.index for s in ramps])
    warnings = _ramp_lag_warnings(session, ramps, lag_tolerance)
    gain = np.eye(3) if reference is None else np.eye(3) + np.asarray(reference.scale_misalignment, float)
    gsens = None if reference is None else reference.g_sensitivity
    rows = []
    g = session.site.gravity
    t0 = float(session.samples["t"].iloc[0])
    for st in ramps:
        df = session.step_samples(st.index)
        t, temp = df["t"].to_numpy(float), df["temp"].to_numpy(float)
        y = df[["gx", "gy", "gz"] if triad == "gyro" else ["ax", "ay", "az"]].to_numpy(float)
        angle = df["table_angle"].to_numpy(float) if "table_angle" in df.columns else np.full(len(t), st.table_angle)
        idx = np.floor((t - t[0]) / window_s).astype(int)
        for w in np.unique(idx):
            sel = idx == w
            if sel.sum() < 3 or np.ptp(angle[sel]) > 1e-6 or t[sel][-1] - t[sel][0] < 0.5 * window_s:
                continue
            force = session.table_attitude(st, float(angle[sel][0])).inv().apply([0.0, 0.0, -g])
            if triad == "gyro":
                true = session.attitude(st, float(angle[sel][0])).inv().apply(earth_rate_ned(session.site.latitude))
                known = gain @ true + (0.0 if gsens is None else gsens @ force)
            else:
                known = gain @ force
            slope = np.polyfit(t[sel] - t[sel][0], temp[sel], 1)[0] * 60.0
            n = sel.sum()
            rows.append((temp[sel].mean(), slope, *(y[sel].mean(0) - known),
                         *(y[sel].std(0, ddof=1) / np.sqrt(n)), st.index, t[sel].mean() - t0))
    if not rows:
        raise AnalysisError(f"{session.name}: ramp steps give no static window of {window_s} s")
    a = np.array(rows)
    rate = a[:, 1]
    direction = np.sign(rate)
    if triad == "accel":
        warnings.append("accel ramp fit: the bias of an axis along gravity includes the scale-factor "
                        "change times g (not separable in one position)")
    return RampSeries(triad, a[:, 0], rate, a[:, 2:5], a[:, 5:8], direction, a[:, 8].astype(int), a[:, 9]), warnings


# ---------------------------------------------------------------------------------------
# whole analysis
@dataclass(frozen=True)
class ThermalResult:
    """Thermal analysis of one session: fits by quantity (``gyro.bias``, ``accel.scale``, ...)."""

    t_ref_c: float
    t_min_c: float
    t_max_c: float
    fits: dict[str, PolyFit]
    soak_points: dict[str, list[SoakPoint]] = field(default_factory=dict)
    ramps: dict[str, RampSeries] = field(default_factory=dict)
    source: str = "soak"
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        """JSON-ready result (SI)."""
        return {
            "source": self.source, "t_ref_c": self.t_ref_c, "t_min_c": self.t_min_c, "t_max_c": self.t_max_c,
            "fits": {q: f.to_dict() for q, f in self.fits.items()},
            "soaks": {tr: [{"soak_step": p.soak_step, "steps": list(p.steps), "setpoint_c": p.setpoint_c,
                            "temperature_c": p.temperature_c, "rate_c_per_min": p.rate_c_per_min,
                            "settle_time_s": p.settle_time_s,
                            "direction": p.direction, "settled": p.settled, "bias": p.bias.tolist(),
                            "bias_sigma": _nan_none(p.bias_sigma), "scale": _nan_none(p.scale),
                            "scale_sigma": _nan_none(p.scale_sigma)} for p in pts]
                      for tr, pts in self.soak_points.items()},
            "warnings": list(self.warnings),
        }


def fit_soaks(points: dict[str, list[SoakPoint]], t_ref_c: float = 25.0, max_order: int = MAX_ORDER,
              order: int | None = None, hysteresis: str = "auto",
              include_unsettled: bool = False, per_axis: bool = True) -> dict[str, PolyFit]:
    """Polynomial fits of bias and (where observed) scale factor over the settled soak points.

    Weights are ``1 / sigma^2`` with each soak's sigma floored at the axis median.
    """
    fits: dict[str, PolyFit] = {}
    for triad, pts in points.items():
        pts = [p for p in pts if p.settled or include_unsettled]
        if not pts:
            raise AnalysisError(f"{triad}: no settled soak to fit")
        tc = np.array([p.temperature_c for p in pts])
        d = np.array([p.direction for p in pts])
        grp = np.array([round(p.setpoint_c if p.setpoint_c is not None else p.temperature_c) for p in pts])
        n_temps = len(np.unique(grp))
        if order is not None and n_temps < order + 1:
            steps = ", ".join(str(p.soak_step) for p in pts)
            raise AnalysisError(f"{triad}: {n_temps} distinct soak temperature(s) (soak steps {steps}); "
                                f"order {order} needs at least {order + 1}")
        for what in ("bias", "scale"):
            vals = np.array([getattr(p, what) for p in pts])
            sig = np.array([getattr(p, what + "_sigma") for p in pts])
            if not np.isfinite(sig).any():
                continue
            # a soak's sigma comes from a handful of positions (few degrees of freedom): raise
            # any below the axis median to it, so no soak dominates the fit by a lucky sigma
            sig = np.maximum(sig, np.nanmedian(sig, axis=0))
            fits[f"{triad}.{what}"] = fit_thermal_poly(tc, vals, sig, d, grp, t_ref_c, max_order, order,
                                                       f"{triad}.{what}", hysteresis, per_axis)
    return fits


def elapsed_at(temperature_c: np.ndarray, elapsed_s: np.ndarray, t_ref_c: float) -> float:
    """Session time (s) at which the sweep first passed ``t_ref_c``, from the unit temperature of
    soaks or ramp windows and their times since the session start: interpolated between the two
    (in time order) that bracket it, else the one nearest to it in temperature."""
    order = np.argsort(elapsed_s)
    temp, t = np.asarray(temperature_c, float)[order], np.asarray(elapsed_s, float)[order]
    for i in range(len(t) - 1):
        a, b = temp[i], temp[i + 1]
        if (a - t_ref_c) * (b - t_ref_c) <= 0 and a != b:
            return float(t[i] + (t_ref_c - a) / (b - a) * (t[i + 1] - t[i]))
    return float(t[np.argmin(np.abs(temp - t_ref_c))])


def with_bias_random_walk(fit: PolyFit, temperature_c: np.ndarray, elapsed_s: np.ndarray,
                          rrw: np.ndarray | float | None) -> PolyFit:
    """``fit`` (a bias fit over a sweep) with the bias random walk in the sigma of its value at t_ref.

    A bias random walk ``K`` (SI per axis: rad/s/√s, m/s²/√s; the Allan result's ``rrw``)
    wanders by ``K sqrt(t)`` from the session start. The points of a sweep (soaks, ramp windows;
    unit temperature ``temperature_c`` °C at ``elapsed_s`` s) follow one another in time, so the
    polynomial absorbs the wander and its value at t_ref carries the wander at the time the
    sweep passed t_ref (:func:`elapsed_at`; the first passage, a lower bound for a return
    sweep): variance ``K^2 t`` is added to the constant term's. The bias the set reports is the
    unit's at power-on, like a multi-position test's at ambient.
    """
    ok = np.isfinite(np.asarray(elapsed_s, float))
    if rrw is None or not ok.any():
        return fit
    t = elapsed_at(np.asarray(temperature_c, float)[ok], np.asarray(elapsed_s, float)[ok], fit.t_ref_c)
    sigma = fit.coeffs_sigma.copy()
    sigma[:, 0] = np.hypot(sigma[:, 0], np.asarray(rrw, float) * np.sqrt(t))
    return replace(fit, coeffs_sigma=sigma)


def analyze_thermal(session, triads=("gyro", "accel"), t_ref_c: float = 25.0, max_order: int = MAX_ORDER,
                    order: int | None = None, hysteresis: str = "auto", settle_tol_c_per_min: float = 0.05,
                    settle_window_s: float = 120.0, ramp_window_s: float = 60.0, reference=None,
                    position_sigma: float | str = 0.0,
                    bias_instability: Mapping[str, np.ndarray | None] | None = None,
                    bias_rrw: Mapping[str, np.ndarray | None] | None = None,
                    order_per_axis: bool = True) -> ThermalResult:
    """Thermal analysis of a session with soak steps (preferred) or ramp steps.

    ``position_sigma`` (rad): the fixture's 1-sigma repeatability, for the per-soak fits;
    ``bias_instability``: triad -> Allan bias instability B (SI), for the per-soak fits;
    ``bias_rrw``: triad -> bias random walk K (SI), for the sigma of the bias at t_ref
    (:func:`with_bias_random_walk`).
    ``reference`` maps triad name -> TriadModel for the ramp fit's known-input term (optional).
    ``order_per_axis``: each axis its own cross-validated order (see :func:`fit_thermal_poly`).
    """
    warnings: list[str] = []
    points: dict[str, list[SoakPoint]] = {}
    ramps: dict[str, RampSeries] = {}
    if not soak_groups(session) and not session.steps_of_kind("ramp"):
        raise SessionError(f"{session.name}: no soak step followed by measurement steps and no ramp step: "
                           "not a thermal session")
    if soak_groups(session):
        points, w = soak_points(session, triads, settle_tol_c_per_min, settle_window_s, position_sigma,
                                bias_instability)
        warnings += w
        fits = fit_soaks(points, t_ref_c, max_order, order, hysteresis, per_axis=order_per_axis)
        for triad, k in (bias_rrw or {}).items():
            settled = [p for p in points.get(triad, []) if p.settled]
            if f"{triad}.bias" in fits:
                fits[f"{triad}.bias"] = with_bias_random_walk(fits[f"{triad}.bias"], [p.temperature_c for p in settled],
                                                              [p.elapsed_s for p in settled], k)
        temps = [p.temperature_c for pts in points.values() for p in pts if p.settled]
        source = "soak"
    else:
        fits = {}
        for triad in triads:
            rs, w = ramp_series(session, triad, ramp_window_s, (reference or {}).get(triad))
            warnings += w
            ramps[triad] = rs
            # folds: eight temperature bands, so a held-out band is a temperature never seen
            edges = np.linspace(rs.temperature_c.min(), rs.temperature_c.max(), 9)
            grp = np.clip(np.digitize(rs.temperature_c, edges[1:-1]), 0, 7)
            fits[f"{triad}.bias"] = with_bias_random_walk(
                fit_thermal_poly(rs.temperature_c, rs.bias, rs.bias_sigma, rs.direction, grp, t_ref_c, max_order,
                                 order, f"{triad}.bias", hysteresis, order_per_axis),
                rs.temperature_c, rs.elapsed_s, (bias_rrw or {}).get(triad))
        temps = [t for rs in ramps.values() for t in rs.temperature_c]
        source = "ramp"
    for f in fits.values():
        warnings += list(f.warnings)
    return ThermalResult(float(t_ref_c), float(min(temps)), float(max(temps)), fits, points, ramps, source,
                         tuple(dict.fromkeys(warnings)))


def to_calibration(result: ThermalResult, unit):
    """The partial CalibrationSet of a thermal result: ``bias``/``diag(M)`` at t_ref + the thermal block.

    The fitted constant terms become ``bias`` and the diagonal of ``M`` (observed); the
    off-diagonal of ``M`` is not observed here (NaN sigma, kept from other procedures on
    merge). Higher terms go to ``thermal.bias_poly`` / ``thermal.scale_poly`` with column 0
    zero. Hysteresis (not part of the model) goes to ``notes['thermal']``.
    """
    from workbench.calset import CalibrationSet, TriadCalibration
    from workbench.model import ThermalModel, TriadModel

    triads, notes = {}, {}
    for triad in ("gyro", "accel"):
        bf, sf = result.fits.get(f"{triad}.bias"), result.fits.get(f"{triad}.scale")
        if bf is None:
            continue
        bias, bias_s = bf.coeffs[:, 0].copy(), bf.coeffs_sigma[:, 0].copy()
        m, m_s = np.zeros((3, 3)), np.full((3, 3), np.nan)
        bpoly, bpoly_s = _poly_block(bf)
        spoly, spoly_s = (np.zeros((3, 0)), np.zeros((3, 0))) if sf is None else _poly_block(sf)
        if sf is not None:
            m[np.diag_indices(3)] = sf.coeffs[:, 0]
            m_s[np.diag_indices(3)] = sf.coeffs_sigma[:, 0]
        model = TriadModel(bias=bias, scale_misalignment=m, thermal=ThermalModel(result.t_ref_c, bpoly, spoly))
        sigma = {"bias": bias_s, "scale_misalignment": m_s, "thermal.bias_poly": bpoly_s,
                 "thermal.scale_poly": spoly_s}
        triads[triad] = TriadCalibration(model, sigma, thermal_range_c=(result.t_min_c, result.t_max_c))
        notes[triad] = {q: {"hysteresis": _nan_none(f.hysteresis), "hysteresis_sigma": _nan_none(f.hysteresis_sigma),
                            "hysteresis_modelled": f.hysteresis_modelled.tolist(), "orders": f.orders.tolist()}
                        for q, f in result.fits.items() if q.startswith(triad + ".")}
    if not triads:
        raise AnalysisError("thermal: no bias fit to put in a calibration set")
    return CalibrationSet(unit=unit, triads=triads, notes={"thermal": notes})


def _poly_block(fit: PolyFit) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients with column 0 moved out to the constant term (zeroed, sigma 0 by construction)."""
    c, s = fit.coeffs.copy(), fit.coeffs_sigma.copy()
    c[:, 0] = 0.0
    s[:, 0] = 0.0
    if c.shape[1] == 1:
        return np.zeros((3, 0)), np.zeros((3, 0))
    return c, s
