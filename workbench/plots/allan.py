"""Allan deviation figures drawn from :class:`workbench.analysis.allan_fit.AllanAnalysis` results.

Log-log ADEV per axis with its 95 % band, each fitted IEEE 952 term as its slope line over
the taus where it dominates (dashed) and the fitted total (thin line); one panel per triad,
in lab units (gyro °/h, accel µg; the legend gives the terms in °/√h, °/h, µg/√Hz, ...).
"""

from __future__ import annotations

from collections.abc import Mapping

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from workbench import units  # noqa: E402
from workbench.analysis.allan_fit import TERMS, AllanAnalysis, basis  # noqa: E402
from workbench.analysis.allan_terms import term_text  # noqa: E402
from workbench.plots.layout import FittedMargins  # noqa: E402

# display unit of the ADEV axis and of each term, per quantity (None = SI of the input)
DEV_UNIT = {"gyro": "deg/h", "accel": "ug", None: "1"}
def plot_triads(analyses: Mapping[str, AllanAnalysis]) -> plt.Figure:
    """One log-log panel per triad (``{"gyro": ..., "accel": ...}``)."""
    fig, axes = plt.subplots(1, len(analyses), figsize=(6.2 * len(analyses), 4.8), squeeze=False,
                             layout=FittedMargins())
    for ax, (name, an) in zip(axes[0], analyses.items()):
        plot_panel(an, ax, title=name)
    return fig


def plot_panel(an: AllanAnalysis, ax: plt.Axes, title: str = "") -> None:
    """Draw one analysis (all its channels) on ``ax``."""
    unit = DEV_UNIT.get(an.quantity, "1")
    f = units.factor(unit)
    c = an.ci.curve
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for j, fit in enumerate(an.fits):
        col = colours[j % len(colours)]
        ax.fill_between(c.tau, an.ci.lo[:, j] / f, an.ci.hi[:, j] / f, color=col, alpha=0.18, lw=0)
        terms = ", ".join(term_text(an.quantity, t, fit.terms[t].value) for t in TERMS if fit.terms[t].observed)
        ax.loglog(c.tau, c.dev[:, j] / f, "o-", ms=3, color=col, label=f"{fit.column}: {terms}")
        grid = np.logspace(np.log10(c.tau[0]), np.log10(c.tau[-1]), 200)
        ax.loglog(grid, fit.model_adev(grid) / f, "-", lw=0.8, color=col)
        for k, t in enumerate(TERMS):
            term = fit.terms[t]
            if term.observed and term.tau_range is not None:
                seg = np.logspace(np.log10(term.tau_range[0]), np.log10(term.tau_range[1]), 20)
                ax.loglog(seg, np.sqrt(basis(seg)[:, k] * fit.theta[k]) / f, "--", lw=1.2, color=col, alpha=0.8)
    ax.set_xlabel("averaging time τ (s)")
    ax.set_ylabel(f"Allan deviation ({units.label(unit) if unit != '1' else 'SI'})")
    ax.set_title(f"{title} (bands: 95 % CI; dashed: fitted terms; thin: fitted total)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="best")
