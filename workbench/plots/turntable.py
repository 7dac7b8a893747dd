"""Figures of turntable calibration results (drawn from :class:`~workbench.analysis.turntable.TriadFit`).

* :func:`plot_residuals`: per-step residuals before and after compensation (mg for an
  accelerometer, °/h for a static gyro fit, °/s for a rate fit), with the 1-sigma of each mean;
  steps that do not fit are marked;
* :func:`plot_rate_tracking`: compensated vs table rate (like thesis Fig. 1.10) with the
  residual in % of full scale;
* :func:`plot_scale_factor_vs_rate`: scale-factor error (ppm) per rate step, before and after;
* :func:`plot_turn_checks`: the hand-made turn checks of a Ferraris session (°).

Lab units on the axes, always labelled.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from workbench.analysis.turntable import TriadFit  # noqa: E402
from workbench.plots.layout import FittedMargins  # noqa: E402
from workbench.units import label, to_unit  # noqa: E402

_XYZ = "xyz"


def _residual_unit(fit: TriadFit) -> str:
    if fit.triad == "accel":
        return "mg"
    rates = fit.residuals[[f"ref_{a}" for a in _XYZ]].abs().to_numpy().max() if len(fit.residuals) else 0.0
    return "deg/s" if rates > 1e-3 else "deg/h"


def plot_residuals(fit: TriadFit):
    """Per-step residuals (reference subtracted) before and after compensation, per axis."""
    r = fit.residuals
    unit = _residual_unit(fit)
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True, layout=FittedMargins())
    x = np.arange(len(r))
    for ax, when in zip(axes, ("before", "after")):
        for k, a in enumerate(_XYZ):
            vals = to_unit(r[f"{when}_{a}"].to_numpy(), unit)
            ax.plot(x + (k - 1) * 0.2, vals, "o", ms=4, label=f"{a}")
            if when == "after":
                ax.errorbar(x + (k - 1) * 0.2, vals, yerr=to_unit(r[f"sigma_{a}"].to_numpy(), unit), fmt="none",
                            ecolor="grey", lw=0.8)
        for i in np.flatnonzero(~r["used"].to_numpy(bool)):
            ax.axvspan(i - 0.45, i + 0.45, color="red", alpha=0.12)
        ax.axhline(0, color="k", lw=0.6)
        ax.set_ylabel(f"{when} compensation [{label(unit)}]")
        ax.grid(alpha=0.3)
    axes[0].legend(ncol=3, fontsize=8)
    axes[0].set_title(f"{fit.triad}: residual per step (reference removed); red = not used (misfit or motion)")
    axes[1].set_xticks(x, [f"{s}\n{lab}" for s, lab in zip(r["step"], r["label"])], rotation=60, fontsize=7)
    return fig


def _rate_rows(fit: TriadFit):
    r = fit.residuals
    ref = r[[f"ref_{a}" for a in _XYZ]].to_numpy()
    axis = np.argmax(np.abs(ref), axis=1)
    idx = np.arange(len(r))
    rate = ref[idx, axis]
    before = r[[f"before_{a}" for a in _XYZ]].to_numpy()[idx, axis]
    after = r[[f"after_{a}" for a in _XYZ]].to_numpy()[idx, axis]
    return axis, rate, before, after


def plot_rate_tracking(fit: TriadFit, full_scale: float):
    """Compensated gyro rate vs table (encoder) rate per rate step, and the residual in % FS."""
    axis, rate, before, after = _rate_rows(fit)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True, layout=FittedMargins())
    for k, (a, mk) in enumerate(zip(_XYZ, "os^")):
        sel = axis == k
        ax1.plot(to_unit(rate[sel], "deg/s"), to_unit(rate[sel] + after[sel], "deg/s"), mk, ms=7 - 2 * k,
                 label=f"gyro {a}")
        ax2.plot(to_unit(rate[sel], "deg/s"), after[sel] / full_scale * 100, mk, ms=4, label=f"{a} after")
        ax2.plot(to_unit(rate[sel], "deg/s"), before[sel] / full_scale * 100, "x", ms=4, alpha=0.5,
                 label=f"{a} before (incl. bias)")
    lim = to_unit(np.abs(rate).max(), "deg/s") * 1.05
    ax1.plot([-lim, lim], [-lim, lim], "k-", lw=0.6, label="table rate")
    ax1.set_ylabel("compensated rate [°/s]")
    ax1.legend(fontsize=8)
    ax1.set_title("compensated gyro vs table rate (encoder + vertical Earth rate)")
    ax2.axhline(0, color="k", lw=0.6)
    ax2.set_ylabel("residual [% of full scale]")
    ax2.set_xlabel("table rate about the axis [°/s]")
    ax2.legend(fontsize=7, ncol=3)
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
    return fig


def plot_scale_factor_vs_rate(fit: TriadFit):
    """Scale-factor error (ppm) per rate step vs rate: raw (offsets removed) and after compensation."""
    axis, rate, before, after = _rate_rows(fit)
    offsets = np.asarray(fit.notes.get("step_offsets", np.zeros((len(rate), 3))))
    idx = np.arange(len(rate))
    raw_sf = (before - offsets[idx, axis]) / rate
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True, layout=FittedMargins())
    for k, (a, mk) in enumerate(zip(_XYZ, "os^")):
        sel = axis == k
        ax1.plot(to_unit(rate[sel], "deg/s"), raw_sf[sel] * 1e6, mk, ms=5, label=f"gyro {a}")
        ax2.plot(to_unit(rate[sel], "deg/s"), after[sel] / rate[sel] * 1e6, mk, ms=5, label=f"gyro {a}")
    ax1.set_title("scale-factor error vs rate about the axis")
    ax1.set_ylabel("raw, offset removed [ppm]")
    ax2.set_ylabel("after compensation [ppm]")
    ax2.set_xlabel("rate about the axis [°/s]")
    for ax in (ax1, ax2):
        ax.axhline(0, color="k", lw=0.6)
        ax.legend(fontsize=8, ncol=3)
        ax.grid(alpha=0.3)
    return fig


def plot_turn_checks(checks: list):
    """Hand-made turn checks (°): integrated angle minus nominal, closure, wobble, tilt, motion around."""
    names = ["angle - nominal", "closure", "wobble rms", "backward", "axis tilt", "gravity change",
             "motion before", "motion after"]
    fig, ax = plt.subplots(figsize=(9, 4.5), layout=FittedMargins())
    width = 0.8 / max(1, len(checks))
    top, bottom = 1e-3, 0.0  # ° (the symlog threshold): limits from the largest bar either way
    for k, c in enumerate(checks):
        vals = np.degrees(np.nan_to_num([abs(c.angle) - np.linalg.norm(c.nominal), c.closure, c.wobble_rms,
                                         c.backward, c.axis_tilt, c.gravity_change, c.motion_before,
                                         c.motion_after]))
        ax.bar(np.arange(len(names)) + k * width, vals, width, label=c.label)
        top, bottom = max(top, float(vals.max())), min(bottom, float(vals.min()))
    ax.set_xticks(np.arange(len(names)) + 0.4 - width / 2, names, rotation=30, fontsize=8)
    ax.set_ylabel("deviation (°)")
    ax.set_yscale("symlog", linthresh=1e-3)
    # a decade of headroom above the largest bar (the legend sits there), as much below a negative one
    ax.set_ylim(-10 * abs(bottom) if bottom < 0 else 0.0, 10 * top)
    ax.set_title("hand-made turns: how far each is from the assumed 360° turn")
    ax.legend(fontsize=8, loc="upper right", ncols=len(checks) or 1)
    ax.grid(alpha=0.3, axis="y")
    return fig
