"""Figures of the AXD-LNS validation, drawn from the stored result payload (thesis Fig. 2.16-2.20).

Public: :func:`lns_figures`, :func:`land_ins_figures`.
"""

from __future__ import annotations

import numpy as np


def lns_figures(payload: dict) -> dict:
    """``trajectory`` (GPS vs the filter, as Fig. 2.16/2.19), ``error_pct`` (error in % of the distance
    since the GPS loss, Fig. 2.17/2.20), ``odo_scale`` (the odometer scale-factor estimate, Fig. 2.18)."""
    from matplotlib.figure import Figure

    from workbench.plots.layout import FittedMargins

    runs, gps, t_loss = payload["runs"], payload["gps"], payload["t_loss"]
    figs = {}
    fig = Figure(figsize=(7, 6), layout=FittedMargins())
    ax = fig.add_subplot()
    lat0, lon0 = gps["lat"][0], gps["lon"][0]
    r_e = 6.371e6

    def en(lat, lon):
        return (np.asarray(lon) - lon0) * r_e * np.cos(lat0) / 1e3, (np.asarray(lat) - lat0) * r_e / 1e3

    ax.plot(*en(gps["lat"], gps["lon"]), ".", ms=1, color="tab:red", label="GPS")
    for name in ("calibrated/sf_state", "calibrated/no_sf_state"):
        r = runs[name]
        ax.plot(*en(r["lat"], r["lon"]), lw=1, label=f"LNS {name}")
    k = int(np.searchsorted(gps["t"], t_loss))
    ax.plot(*en([gps["lat"][k]], [gps["lon"][k]]), "o", color="green", ms=8, label="GPS loss")
    ax.set(xlabel="east (km)", ylabel="north (km)", title="Drive: GPS and AXD-LNS (thesis Fig. 2.16 / 2.19)")
    ax.set_aspect("equal")
    ax.legend(fontsize=7)
    figs["trajectory"] = fig
    fig = Figure(figsize=(7, 4), layout=FittedMargins())
    ax = fig.add_subplot()
    for name, r in runs.items():
        d = np.asarray(r["distance_m"])
        with np.errstate(divide="ignore", invalid="ignore"):
            pct = 100 * np.asarray(r["error_m"]) / d
        ax.plot(d / 1e3, pct, lw=1, label=name)
    ax.axhline(3.0, color="k", ls="--", lw=0.8, label="requirement 3 %")
    ax.set(xlabel="distance since GPS loss (km)", ylabel="position error (% of distance)", ylim=(0, 10),
           title="Error after the GPS loss (thesis Fig. 2.17 / 2.20)")
    ax.legend(fontsize=7)
    figs["error_pct"] = fig
    fig = Figure(figsize=(7, 3.5), layout=FittedMargins())
    ax = fig.add_subplot()
    for name, r in runs.items():
        if name.endswith("/sf_state"):
            ax.plot(r["t_all"], 100 * np.asarray(r["odo_scale"]), lw=1, label=name)
    ax.axvline(t_loss, color="green", lw=0.8, label="GPS loss")
    ax.set(xlabel="time (s)", ylabel="odometer SF error (%)", title="Odometer scale factor (thesis Fig. 2.18)")
    ax.legend(fontsize=7)
    figs["odo_scale"] = fig
    return figs


def land_ins_figures(payload: dict) -> dict:
    """``horizontal_error``: error against the reference and the filter's 1-sigma over time, raw and
    calibrated (paper 001 Fig. 4-4 style)."""
    from matplotlib.figure import Figure

    from workbench.plots.layout import FittedMargins

    fig = Figure(figsize=(7, 4), layout=FittedMargins())
    ax = fig.add_subplot()
    for mode, r in payload["runs"].items():
        if "error_m" in r:
            ax.plot(r["t_ref"], r["error_m"], lw=1, label=f"{mode}: error vs reference")
        ax.plot(r["t"], np.hypot(r["sigma_n"], r["sigma_e"]), lw=0.8, ls="--", label=f"{mode}: filter 1-sigma")
    ax.set(xlabel="time (s)", ylabel="horizontal position (m)", yscale="log",
           title="Land INS with NHC / ZUPT / ZARUPT (paper 001)")
    ax.legend(fontsize=7)
    return {"horizontal_error": fig}
