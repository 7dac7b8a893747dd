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
    """Lines for people in the lab units of :data:`workbench.units.QUANTITIES`: bias (mg or °/h),
    scale factor and asymmetry (ppm), misalignment (mrad), nonlinearity (µg/g² or ppm/(°/s)),
    g-sensitivity (°/h/g), residuals before/after (mg, or °/s and % of ``full_scale`` (rad/s) for a
    rate fit). One unit per figure (``x 2.355 ± 0.2 mg``); only observed coefficients (finite sigma).
    """
    acc = fit.triad == "accel"
    t = fit.triad

    def per_axis(quantity: str, values, sigmas, digits: int = 4) -> str:
        return ", ".join(f"{a} {units.show(t, quantity, v, s, digits)}"
                         for a, v, s in zip("xyz", values, sigmas) if np.isfinite(s))

    lines = []
    if np.isfinite(fit.bias_sigma).any():
        lines.append(f"{t} bias: " + per_axis("bias", fit.bias, fit.bias_sigma))
    d, ds = np.diag(fit.scale_misalignment), np.diag(fit.scale_misalignment_sigma)
    if np.isfinite(ds).any():
        lines.append(f"{t} scale factor: " + per_axis("scale_factor", d, ds, 5))
        off = ~np.eye(3, dtype=bool)
        worst = np.abs(fit.scale_misalignment[off]).max()
        mis = units.unit_of(t, "misalignment")
        lines.append(f"{t} misalignment: largest |M_ij| {units.fmt(worst, mis, 3)}, "
                     f"largest sigma {units.fmt(np.nanmax(fit.scale_misalignment_sigma[off]), mis, 2)}")
    if np.isfinite(fit.nonlinearity_sigma).any():
        lines.append(f"{t} nonlinearity: " + per_axis("nonlinearity", fit.nonlinearity, fit.nonlinearity_sigma, 3))
    if np.isfinite(fit.asymmetry_sigma).any():
        lines.append(f"{t} scale-factor asymmetry (SF+ - SF-)/2: "
                     + per_axis("scale_factor", fit.asymmetry, fit.asymmetry_sigma, 3))
    if fit.g_sensitivity is not None and np.isfinite(fit.g_sensitivity_sigma).any():
        gs = units.unit_of(t, "g_sensitivity")
        lines.append(f"{t} g-sensitivity: largest |G_ij| {units.fmt(np.abs(fit.g_sensitivity).max(), gs, 3)} "
                     f"(largest sigma {units.fmt(np.nanmax(fit.g_sensitivity_sigma), gs, 2)})")
    r = fit.residuals[fit.residuals["used"]] if len(fit.residuals) else fit.residuals
    if len(r):
        before = np.abs(r[["before_x", "before_y", "before_z"]].to_numpy()).max()
        after = np.abs(r[["after_x", "after_y", "after_z"]].to_numpy()).max()
        res_unit = units.unit_of(t, "residual")
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
        elif k == "g_sensitivity":
            lines.append(f"{t} g-sensitivity: {v}")
    return lines
