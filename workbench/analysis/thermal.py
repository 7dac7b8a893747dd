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

from workbench.analysis.thermal_points import (RampSeries, SoakGroup, SoakPoint, ramp_series, soak_groups,  # noqa: F401
                                               soak_points)
from workbench.analysis.thermal_poly import MAX_ORDER, PolyFit, _nan_none, coefficient_sigma, fit_thermal_poly  # noqa: F401
from workbench.analysis.thermal_settling import Settling, settling, windowed_slope  # noqa: F401
from workbench.errors import AnalysisError, SessionError
from workbench.units import fit_unit, label, to_unit

QUANTITIES = ("gyro.bias", "gyro.scale", "accel.bias", "accel.scale")


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

    def summary(self) -> list[str]:
        """Lines for people: the range and t_ref (°C), per quantity the order per axis, the held-out
        RMS and the hysteresis in the quantity's lab unit (°/h, mg, ppm)."""
        lines = [f"thermal ({self.source}): {self.t_min_c:.1f}..{self.t_max_c:.1f} °C, t_ref {self.t_ref_c:g} °C"]
        for q, f in self.fits.items():
            unit = fit_unit(q)
            rms = ", ".join(f"{v:.3g}" for v in to_unit(f.cv_rms_chosen, unit))
            orders = ", ".join(f"{a} {k}" for a, k in zip("xyz", f.orders))
            line = f"{q}: order {orders} (per axis), held-out RMS [{rms}] {label(unit)}"
            if np.isfinite(f.hysteresis).any():
                h = ", ".join(f"{a:.3g}±{b:.2g}" for a, b in zip(to_unit(f.hysteresis, unit),
                                                                 to_unit(f.hysteresis_sigma, unit)))
                line += (f"; hysteresis (up - down) [{h}] {label(unit)}"
                         + (" (modelled)" if f.hysteresis_modelled.any() else ""))
            lines.append(line)
        return lines

    def to_calibration(self, unit):
        """The partial calibration set of ``unit`` (a :class:`workbench.calset.Unit`): see :func:`to_calibration`."""
        return to_calibration(self, unit)


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


def with_bias_random_walk(fit: PolyFit, temperature_c: np.ndarray, elapsed_s: np.ndarray,
                          rrw: np.ndarray | float | None) -> PolyFit:
    """``fit`` (a bias fit over a sweep) with the bias random walk in the sigmas of its coefficients.

    A bias random walk ``K`` (SI per axis: rad/s/√s, m/s²/√s; the Allan result's ``rrw``)
    wanders by ``K sqrt(t)`` from the session start. The points of a sweep (soaks, ramp windows;
    unit temperature ``temperature_c`` °C at ``elapsed_s`` s since the session start, in the
    fit's order) follow one another in time, so the walk is common to neighbours: covariance
    ``K^2 min(t_i, t_j)``. A sweep that climbs in temperature turns the walk into a slope, and
    the polynomial's value at t_ref carries the walk since power-on (the bias the set reports
    is the unit's at power-on, like a multi-position test's at ambient). Each coefficient's
    sigma becomes the larger of the fit's own (Birge-scaled, held-out floor) and the sandwich
    sigma under the walk (:func:`coefficient_sigma`). Unchanged without ``rrw`` or without
    the points' times.
    """
    t = np.asarray(elapsed_s, float)
    if rrw is None or len(t) != len(fit.temperature_c) or not np.isfinite(t).all():
        return fit
    k2 = np.broadcast_to(np.asarray(rrw, float) ** 2, (3,))
    walk = k2[:, None, None] * np.minimum.outer(t, t)[None]
    return replace(fit, coeffs_sigma=np.fmax(fit.coeffs_sigma, coefficient_sigma(fit, walk)))


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
    groups = soak_groups(session, settle_tol_c_per_min, settle_window_s)  # found from the data without soak steps
    if not groups and not session.steps_of_kind("ramp"):
        raise SessionError(f"{session.name}: no soak step followed by measurement steps, no holds at two or more "
                           "setpoints or unit temperatures, and no ramp step: not a thermal session")
    if groups:
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
