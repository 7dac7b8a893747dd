"""Figures of thermal results (drawn from :class:`~workbench.analysis.thermal.ThermalResult`).

* :func:`quantity_figure`: one quantity (e.g. gyro bias) per axis against the unit
  temperature, measured points with 1-sigma bars, up branch red and down branch blue, the
  fitted curve (per branch when the hysteresis term is modelled, else the mid-branch curve);
* :func:`residual_figure`: residuals after compensation by the fitted model, per axis;
* :func:`order_figure`: held-out RMS residual against polynomial order, per axis;
* :func:`thermal_figures`: the set the procedure's ``figures(result)`` returns.

Lab units on the axes (°/s, mg, ppm), always labelled.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from workbench.analysis.thermal import PolyFit, ThermalResult  # noqa: E402
from workbench.plots.layout import FittedMargins  # noqa: E402
from workbench.units import fit_unit, label, to_unit  # noqa: E402

BRANCH_COLOURS = {1: "tab:red", -1: "tab:blue", 0: "tab:grey"}
BRANCH_NAMES = {1: "up (warming)", -1: "down (cooling)", 0: "no direction"}


def display_unit(quantity: str) -> str:
    """Lab unit of a fitted quantity from ``workbench.units`` (``gyro.bias`` -> deg/h, ``accel.bias`` -> mg,
    ``*.scale`` -> ppm)."""
    return fit_unit(quantity)


def quantity_figure(fit: PolyFit):
    """Measured values and the fitted temperature model of ``fit``, one panel per axis."""
    unit = display_unit(fit.quantity)
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8), sharex=True, layout=FittedMargins())
    grid = np.linspace(fit.temperature_c.min(), fit.temperature_c.max(), 200)
    for ax_i, ax in enumerate(axes):
        for d in (1, -1, 0):
            sel = fit.direction == d
            if sel.any():
                ax.errorbar(fit.temperature_c[sel], to_unit(fit.values[sel, ax_i], unit),
                            yerr=to_unit(np.nan_to_num(fit.sigma[sel, ax_i]), unit), fmt="o", ms=3,
                            color=BRANCH_COLOURS[d], label=BRANCH_NAMES[d])
        if fit.hysteresis_modelled[ax_i]:
            for d in (1, -1):
                ax.plot(grid, to_unit(fit.predict(grid, np.full(grid.size, d))[:, ax_i], unit), "-",
                        color=BRANCH_COLOURS[d], lw=1)
        else:
            ax.plot(grid, to_unit(fit.predict(grid)[:, ax_i], unit), "k-", lw=1, label="fit")
        ax.set_title(f"{fit.quantity} {'xyz'[ax_i]} (order {fit.orders[ax_i]})")
        ax.set_xlabel("unit temperature (°C)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(f"{fit.quantity} ({label(unit)})")
    axes[0].legend(fontsize=7)
    return fig


def residual_figure(fit: PolyFit):
    """Residuals after compensation (measured minus model) against the unit temperature."""
    unit = display_unit(fit.quantity)
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.4), sharex=True, layout=FittedMargins())
    for ax_i, ax in enumerate(axes):
        for d in (1, -1, 0):
            sel = fit.direction == d
            if sel.any():
                ax.plot(fit.temperature_c[sel], to_unit(fit.residuals[sel, ax_i], unit), "o", ms=3,
                        color=BRANCH_COLOURS[d], label=BRANCH_NAMES[d])
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set_title(f"{fit.quantity} {'xyz'[ax_i]}: held-out RMS "
                     f"{to_unit(fit.cv_rms_chosen[ax_i], unit):.3g} {label(unit)}")
        ax.set_xlabel("unit temperature (°C)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(f"residual after compensation ({label(unit)})")
    axes[0].legend(fontsize=7)
    return fig


def order_figure(fit: PolyFit):
    """Held-out RMS residual (log scale) against polynomial order, per axis; chosen order marked."""
    unit = display_unit(fit.quantity)
    fig, ax = plt.subplots(figsize=(6, 3.8), layout=FittedMargins())
    orders = np.array(fit.cv_orders)
    for ax_i in range(3):
        line = ax.semilogy(orders, to_unit(fit.cv_rms[:, ax_i], unit), "o-", label=f"{'xyz'[ax_i]}")[0]
        if np.isfinite(fit.cv_rms_hysteresis[:, ax_i]).any():
            ax.semilogy(orders, to_unit(fit.cv_rms_hysteresis[:, ax_i], unit), "s--", color=line.get_color(),
                        ms=3, label=f"{'xyz'[ax_i]} + hysteresis term")
        ax.axvline(fit.orders[ax_i] + 0.04 * (ax_i - 1), color=line.get_color(), ls=":",
                   label=f"{'xyz'[ax_i]}: chosen order {fit.orders[ax_i]}")
    ax.set_xlabel("polynomial order")
    ax.set_ylabel(f"held-out RMS ({label(unit)})")
    ax.set_title(f"{fit.quantity}: cross-validation")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    return fig


def thermal_figures(result: ThermalResult) -> dict:
    """All figures of a thermal result, keyed ``<quantity>_fit``, ``_residuals``, ``_order``."""
    figs = {}
    for q, fit in result.fits.items():
        name = q.replace(".", "_")
        figs[f"{name}_fit"] = quantity_figure(fit)
        figs[f"{name}_residuals"] = residual_figure(fit)
        figs[f"{name}_order"] = order_figure(fit)
    return figs
