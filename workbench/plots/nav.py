"""Figures of the navigation validations, drawn from the filters' result objects.

ZUPT alignment like thesis (shared/seeds/000_...) Fig. 3.6-3.10 (attitude, gyro biases,
position, NED velocity, accelerometer biases), raw against calibrated; AHRS attitude errors
against the table like paper 004 (shared/seeds/004_...) Fig. 15 (heading before and after
calibration). Lab units on the axes (°, °/h, mg, mm/s), always labelled.

Public: :func:`zupt_figures`, :func:`ahrs_figures`.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from workbench import units  # noqa: E402
from workbench.plots.layout import FittedMargins  # noqa: E402

_STYLE = {"raw": {"color": "tab:red", "alpha": 0.8}, "calibrated": {"color": "tab:blue"}}


def _axes3(title: str, ylabel: str, names=("x", "y", "z")):
    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True, layout=FittedMargins())
    fig.suptitle(title)
    for ax, n in zip(axes, names):
        ax.set_ylabel(f"{n} [{ylabel}]")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time since EKF start [s]")
    return fig, axes


def zupt_figures(payload: dict) -> dict:
    """Per position: attitude (Fig. 3.6), gyro bias (3.7), position (3.8), velocity (3.9), accel bias (3.10).

    ``payload``: ``{"labels": [...], "raw": [{"result": ZuptResult, ...}], "calibrated": [...]}``.
    Gyro and accel biases are drawn with their ±3-sigma bands.
    """
    figs = {}
    for i, label in enumerate(payload["labels"]):
        key = label.replace(" ", "_").replace("°", "deg")
        specs = [
            ("attitude", "Roll, pitch, heading (thesis Fig. 3.6)", "°", ("roll", "pitch", "heading"),
             lambda r: np.degrees(r.rph), None),
            ("gyro_bias", "Gyro bias estimate ±3σ (thesis Fig. 3.7)", "°/h", ("x", "y", "z"),
             lambda r: units.to_unit(r.gyro_bias, "deg/h"), lambda r: units.to_unit(r.gyro_bias_sigma, "deg/h")),
            ("position", "Position offset from the frozen solution (thesis Fig. 3.8)", "mm", ("north", "east", "down"),
             lambda r: r.position * 1e3, None),
            ("velocity", "NED velocity (thesis Fig. 3.9)", "mm/s", ("north", "east", "down"),
             lambda r: r.velocity * 1e3, None),
            ("accel_bias", "Accelerometer bias estimate ±3σ (thesis Fig. 3.10)", "mg", ("x", "y", "z"),
             lambda r: units.to_unit(r.accel_bias, "mg"), lambda r: units.to_unit(r.accel_bias_sigma, "mg")),
        ]
        for name, title, unit, comps, value, sigma in specs:
            fig, axes = _axes3(f"{title} — {label}", unit, comps)
            for mode in ("raw", "calibrated"):
                res = payload[mode][i]["result"]
                t = res.t - res.t_start
                v = value(res)
                for j, ax in enumerate(axes):
                    ax.plot(t, v[:, j], label=mode, lw=1.2, **_STYLE[mode])
                    if sigma is not None:
                        s = sigma(res)
                        ax.fill_between(t, v[:, j] - 3 * s[:, j], v[:, j] + 3 * s[:, j], alpha=0.15,
                                        color=_STYLE[mode]["color"])
            axes[0].legend(loc="upper right")
            figs[f"{name}_{key}"] = fig
    return figs


def ahrs_figures(payload: dict) -> dict:
    """Attitude errors against the table (roll, pitch, heading), raw vs calibrated, per filter.

    ``payload``: ``{"raw": {filter: {"t": (E,), "errors_deg": (E, 3)}}, "calibrated": {...}}``.
    """
    figs = {}
    for filt in payload["calibrated"]:
        fig, axes = _axes3(f"AHRS ({filt}) attitude error against the table (paper 004 Fig. 15)", "°",
                           ("roll", "pitch", "heading"))
        for mode in ("raw", "calibrated"):
            d = payload[mode][filt]
            for j, ax in enumerate(axes):
                ax.plot(d["t"], d["errors_deg"][:, j], label=mode, lw=1.0, **_STYLE[mode])
        axes[-1].set_xlabel("time [s]")
        axes[0].legend(loc="upper right")
        figs[f"attitude_error_{filt}"] = fig
    return figs
