"""Figure of a hand-held magnetometer fit: field norm and field-to-gravity angle against time.

Drawn from :class:`workbench.analysis.mag_holdout.FreeQuality` (its ``series``): the calibrated field
norm (% from the fitted norm) and the angle between field and gravity (°) at every fitted point,
under the chosen fit and under the plain algebraic ellipsoid, with the held-out split marked.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from workbench.analysis.mag_holdout import FreeQuality
from workbench.plots.layout import FittedMargins


def plot_free_quality(q: FreeQuality) -> plt.Figure:
    """Two panels against time (s): field norm deviation (%) and field-to-gravity angle (°)."""
    fig, (ax_n, ax_a) = plt.subplots(2, 1, figsize=(9, 6), sharex=True, layout=FittedMargins())
    s = q.series or {}
    if "t" not in s:
        ax_n.text(0.5, 0.5, "no per-point figures stored", ha="center", transform=ax_n.transAxes)
        return fig
    t = s["t"]
    for key, label, color, fig_of in (("plain", "plain 10-coefficient ellipsoid", "tab:orange", q.baseline),
                                      ("fit", "chosen fit", "tab:blue", q.fit)):
        if f"{key}_norm" not in s or fig_of is None:
            continue
        ax_n.plot(t, 100 * s[f"{key}_norm"], ".", ms=2, color=color,
                  label=f"{label}: RMS {100 * fig_of.norm_rms:.2f} % (held out {100 * fig_of.norm_rms_held_out:.2f} %)")
        ax_a.plot(t, np.degrees(s[f"{key}_angle"]), ".", ms=2, color=color,
                  label=f"{label}: spread {np.degrees(fig_of.angle_spread):.2f}° "
                        f"(held out {np.degrees(fig_of.angle_spread_held_out):.2f}°)")
    for ax in (ax_n, ax_a):
        ax.axvline(q.split_t, color="k", lw=0.8, ls="--")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    ax_n.set_ylabel("field norm − fitted norm (%)")
    ax_a.set_ylabel("angle field to gravity (°)\n(points whose gravity is known)")
    ax_a.set_xlabel("time (s); dashed: held-out split (fit before, judge after)")
    ax_n.set_title(f"Hand-held magnetometer fit, {q.n_points} points (no truth needed)")
    return fig
