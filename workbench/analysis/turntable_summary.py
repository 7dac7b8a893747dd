"""Summary lines of a turntable fit (:class:`~workbench.analysis.turntable_fit.TriadFit`) in lab units.

:func:`triad_summary` is what ``TriadFit.summary()`` returns: bias (°/h or mg), scale factor (ppm),
misalignment (mrad), nonlinearity, asymmetry, g-sensitivity (°/h/g) and the residuals per step
before and after compensation, all through :mod:`workbench.units`. Part of
:mod:`workbench.analysis.turntable`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from workbench import units

if TYPE_CHECKING:
    from workbench.analysis.turntable_fit import TriadFit


def triad_summary(fit: TriadFit, full_scale: float | None = None) -> list[str]:
    """Lines for people in lab units: bias (mg or °/h), scale factor (ppm), misalignment (mrad),
    nonlinearity and residuals before/after (mg, or °/s and % of ``full_scale`` (rad/s) for a rate fit).

    Only observed coefficients (finite sigma) are listed.
    """
    acc = fit.triad == "accel"
    b_unit = "mg" if acc else "deg/h"

    def pm(v, s, unit, digits=4):
        return f"{units.fmt(v, unit, digits)} ± {units.fmt(s, unit, 2)}"

    t = fit.triad
    lines = []
    if np.isfinite(fit.bias_sigma).any():
        lines.append(f"{t} bias: " + ", ".join(f"{a} {pm(v, s, b_unit)}"
                                               for a, v, s in zip("xyz", fit.bias, fit.bias_sigma)))
    d, ds = np.diag(fit.scale_misalignment), np.diag(fit.scale_misalignment_sigma)
    if np.isfinite(ds).any():
        lines.append(f"{t} scale factor: " + ", ".join(f"{a} {pm(v, s, 'ppm', 5)}" for a, v, s in zip("xyz", d, ds)))
        off = ~np.eye(3, dtype=bool)
        worst = np.abs(fit.scale_misalignment[off]).max()
        lines.append(f"{t} misalignment: largest |M_ij| {units.fmt(worst, 'mrad', 3)}, "
                     f"largest sigma {units.fmt(np.nanmax(fit.scale_misalignment_sigma[off]), 'mrad', 2)}")
    if np.isfinite(fit.nonlinearity_sigma).any():
        lines.append(f"{t} nonlinearity (1/SI): " + ", ".join(
            f"{a} {v:.3g} ± {s:.2g}" for a, v, s in zip("xyz", fit.nonlinearity, fit.nonlinearity_sigma)
            if np.isfinite(s)))
    if np.isfinite(fit.asymmetry_sigma).any():
        lines.append(f"{t} scale-factor asymmetry (SF+ - SF-)/2: " + ", ".join(
            f"{a} {pm(v, s, 'ppm', 3)}" for a, v, s in zip("xyz", fit.asymmetry, fit.asymmetry_sigma)))
    if fit.g_sensitivity is not None and np.isfinite(fit.g_sensitivity_sigma).any():
        gs = units.factor("deg/h") / units.factor("g")
        lines.append(f"{t} g-sensitivity: largest |G_ij| {np.abs(fit.g_sensitivity).max() / gs:.3g} °/h/g "
                     f"(largest sigma {np.nanmax(fit.g_sensitivity_sigma) / gs:.2g} °/h/g)")
    r = fit.residuals[fit.residuals["used"]] if len(fit.residuals) else fit.residuals
    if len(r):
        before = np.abs(r[["before_x", "before_y", "before_z"]].to_numpy()).max()
        after = np.abs(r[["after_x", "after_y", "after_z"]].to_numpy()).max()
        res_unit = "mg" if acc else "deg/s"
        line = (f"{t} max residual per step: before {units.fmt(before, res_unit, 3)}, "
                f"after {units.fmt(after, res_unit, 3)}")
        if full_scale:
            line += f" ({after / full_scale * 100:.3g} % of full scale {units.fmt(full_scale, 'deg/s', 4)})"
        lines.append(line)
        if acc:
            lines.append(f"{t} max | |a| - g | per step: before {units.fmt(np.abs(r['before_norm']).max(), 'mg', 3)}, "
                         f"after {units.fmt(np.abs(r['after_norm']).max(), 'mg', 3)}")
    for k, v in fit.notes.items():
        if k == "earth_rate":
            lines.append(f"{t} Earth rate: {v}")
    return lines
