"""Magnetometer figures, drawn from a :class:`workbench.analysis.magnetometer.MagCalibration`.

- :func:`plot_cloud`: raw and calibrated points in the three axis planes, with the fitted
  field-norm circle (paper 004 Fig. 5, 8, 12, 14);
- :func:`plot_heading_error`: heading error against the table azimuth before calibration,
  with the plain algebraic fit and with the chosen fit (paper 004 Fig. 15).
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from workbench.analysis.magnetometer import MagCalibration  # noqa: E402
from workbench.angles import wrap_2pi  # noqa: E402
from workbench.plots.layout import FittedMargins  # noqa: E402

_PLANES = ((0, 1), (0, 2), (1, 2))
_AXES = "xyz"


def plot_cloud(cal: MagCalibration) -> plt.Figure:
    """Raw vs calibrated magnetometer points (µT) in the xy, xz and yz planes."""
    raw = cal.points.mag
    calibrated = cal.fit.compensate(raw)
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.4), layout=FittedMargins())
    circle = np.linspace(0, 2 * np.pi, 361)
    r = cal.fit.field_norm_ut
    for ax, (i, j) in zip(axes, _PLANES):
        ax.plot(raw[:, i], raw[:, j], ".", ms=3, color="tab:red", alpha=0.6, label="raw")
        ax.plot(calibrated[:, i], calibrated[:, j], ".", ms=3, color="tab:blue", alpha=0.6, label="calibrated")
        ax.plot(r * np.cos(circle), r * np.sin(circle), "k:", lw=0.8, label=f"|B| = {r:.1f} µT")
        ax.set_xlabel(f"m{_AXES[i]} [µT]")
        ax.set_ylabel(f"m{_AXES[j]} [µT]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="best", fontsize=8)
    fig.suptitle(f"Magnetometer points, method {cal.fit.method} "
                 f"(coverage {cal.quality.coverage:.0%}, {len(cal.points)} points)")
    return fig


def plot_heading_error(cal: MagCalibration) -> plt.Figure:
    """Heading error (°) against the table azimuth (°): raw, plain algebraic fit, chosen fit."""
    fig, ax = plt.subplots(figsize=(9, 4.5), layout=FittedMargins())
    if cal.heading is None:
        ax.text(0.5, 0.5, "no attitude: heading error not evaluated", ha="center", transform=ax.transAxes)
        return fig
    series = [(cal.raw_heading, "uncalibrated", "tab:red", "x"),
              (cal.baseline_heading, "plain algebraic fit", "tab:orange", "s"),
              (cal.heading, f"{cal.fit.method} fit", "tab:blue", "o")]
    for ev, name, color, marker in series:
        if ev is None:
            continue
        az = np.degrees(wrap_2pi(ev.reference))
        ax.plot(az, np.degrees(ev.error), marker, ms=4, color=color, ls="none",
                label=f"{name}: RMS {np.degrees(ev.rms):.3g}°")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("table azimuth of body x [°]")
    ax.set_ylabel("heading error [°]")
    ax.set_xlim(0, 360)
    ax.set_yscale("symlog", linthresh=0.1)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    src = "estimated as mean offset" if cal.heading.declination_estimated else "fitted or given"
    ax.set_title(f"Tilt-compensated heading error (declination {np.degrees(cal.heading.declination):.2f}°, {src})")
    return fig
