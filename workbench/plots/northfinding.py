"""Figures of north-finding results (drawn from :class:`~workbench.analysis.northfinding.NorthFinding`).

* :func:`earth_rate_figure`: gyro output (bias and drift removed) vs table angle with the
  fitted Earth-rate sinusoids, like thesis Fig. 4.6;
* :func:`azimuth_figure`: azimuth per pair / turn / lap about the mean, like Fig. 4.7-4.13;
* :func:`pairing_figure`: redundant configuration, azimuth per pairing and turn (Fig. 4.16-4.23);
* :func:`repeatability_figure`: session means about the mean of all (Fig. 4.14-4.15) from
  :func:`~workbench.analysis.northfinding.sequence_table` rows;
* :func:`procedure_figures`: the set a procedure's ``figures(result)`` returns.

Lab units on the axes (°/h, °, mrad), always labelled.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from workbench.analysis.northfinding import NorthFinding, RedundantResult, angle_diff  # noqa: E402
from workbench.angles import wrap_2pi  # noqa: E402
from workbench.plots.layout import FittedMargins  # noqa: E402
from workbench.units import to_unit  # noqa: E402


def earth_rate_figure(nf: NorthFinding):
    """Level-axis gyro outputs (°/h, bias and drift removed) vs table angle (°) with the fit."""
    fig, ax = plt.subplots(figsize=(8, 4.5), layout=FittedMargins())
    obs, fit, geom = nf.obs, nf.fit, nf.geometry
    drift = np.nan_to_num(fit.drift) * (obs.t - fit.t_ref)[:, None]
    grid = np.linspace(0.0, 2 * np.pi, 361)
    model = fit.model(grid, geom, nf.latitude) - fit.bias
    ang = np.degrees(wrap_2pi(obs.angle))
    for i in np.flatnonzero(geom.horizontal):
        meas = obs.rate[:, i] - fit.bias[i] - drift[:, i]
        line = ax.plot(ang, to_unit(meas, "deg/h"), ".", ms=3, label=f"gyro {'xyz'[i]}")[0]
        ax.plot(np.degrees(grid), to_unit(model[:, i], "deg/h"), "-", color=line.get_color(), lw=1)
    amp = to_unit(nf.expected_amplitude, "deg/h")
    ax.axhline(amp, color="grey", ls=":", lw=0.8)
    ax.axhline(-amp, color="grey", ls=":", lw=0.8, label="±Ω_e cos(lat)")
    ax.set_xlabel("table angle [°]")
    ax.set_ylabel("gyro output − bias [°/h]")
    ax.set_title(f"Horizontal Earth rate: fitted {to_unit(nf.earth_rate_amplitude, 'deg/h'):.3f} °/h, "
                 f"expected {amp:.3f} °/h")
    ax.set_xlim(0, 360)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def azimuth_figure(nf: NorthFinding):
    """Azimuth per unit (pair, turn, lap) as the distance from the mean (mrad) vs time (min)."""
    fig, ax = plt.subplots(figsize=(8, 4.5), layout=FittedMargins())
    dev = angle_diff(nf.unit_azimuth, nf.azimuth) * 1e3
    ax.plot(nf.unit_time / 60.0, dev, "o-", ms=3, lw=0.6, label=f"per {nf.units}")
    ax.axhline(0.0, color="k", lw=1, label=f"mean {np.degrees(wrap_2pi(nf.azimuth)):.3f}°")
    for sgn in (-1, 1):
        ax.axhline(sgn * nf.unit_std * 1e3, color="C1", ls="--", lw=0.8,
                   label=f"±1σ per {nf.units} = {nf.unit_std * 1e3:.2f} mrad" if sgn > 0 else None)
    th = nf.theory["allan_unit_sigma"] * 1e3
    if np.isfinite(th):
        ax.axhspan(-th, th, color="C2", alpha=0.12, label=f"±theory (ADEV) {th:.2f} mrad")
    ax.set_xlabel("time [min]")
    ax.set_ylabel("azimuth − mean [mrad]")
    err = "" if nf.azimuth_error is None else f", error {nf.azimuth_error * 1e3:+.2f} mrad"
    ax.set_title(f"{nf.method}: azimuth {np.degrees(wrap_2pi(nf.azimuth)):.3f} ± {np.degrees(nf.azimuth_sigma):.2g}° "
                 f"(1σ = {nf.azimuth_sigma * 1e3:.2f} mrad){err}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def pairing_figure(nf: NorthFinding):
    """Redundant configuration: each pairing's azimuth per turn about the all-pairing mean (mrad)."""
    d = nf.detail
    if not isinstance(d, RedundantResult):
        raise TypeError("pairing_figure needs a redundant-configuration result")
    fig, ax = plt.subplots(figsize=(8, 4.5), layout=FittedMargins())
    k = np.arange(len(d.pairings))
    dev = angle_diff(d.azimuth, nf.azimuth) * 1e3
    for t in range(dev.shape[0]):
        ax.plot(k + 0.03 * (t - dev.shape[0] / 2), dev[t], ".", color="C0", ms=4, alpha=0.6)
    ax.errorbar(k, angle_diff(d.mean, nf.azimuth) * 1e3, yerr=d.std * 1e3, fmt="s", color="C3", capsize=3,
                label="mean ± std over turns")
    ax.set_xticks(k, [f"{p}°" for p in d.pairings])
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xlabel("pairing")
    ax.set_ylabel("azimuth − mean of all [mrad]")
    ax.set_title(f"Redundant configuration: {dev.shape[0]} turns, bias {d.bias_source}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def repeatability_figure(rows: list[dict], title: str = "Azimuth repeatability over sequences"):
    """Distance of each session's mean from the mean of all (mrad), from ``sequence_table`` rows."""
    fig, ax = plt.subplots(figsize=(6, 4), layout=FittedMargins())
    labels = [r["sequence"] for r in rows]
    dist = [r["distance_mrad"] for r in rows]
    ax.errorbar(range(len(rows)), dist, yerr=[r["sigma_mrad"] for r in rows], fmt="o", capsize=3)
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xticks(range(len(rows)), labels)
    ax.set_xlabel("sequence")
    ax.set_ylabel("mean − mean of all [mrad]")
    ax.set_title(f"{title}: max {max(abs(d) for d in dist):.2f} mrad")
    ax.grid(alpha=0.3)
    return fig


def procedure_figures(nf: NorthFinding) -> dict:
    """Figures of one session: ``earth_rate``, ``azimuth`` and, for the redundant method, ``pairings``."""
    figs = {"earth_rate": earth_rate_figure(nf), "azimuth": azimuth_figure(nf)}
    if isinstance(nf.detail, RedundantResult):
        figs["pairings"] = pairing_figure(nf)
    return figs
