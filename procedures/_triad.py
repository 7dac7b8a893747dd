"""What the triad-calibration procedures (multiposition, rate, ferraris) share: the result dict.

:func:`result_dict` (each fit's estimates and sigmas, SI, with its residual table); the summary
lines are the fit's own (``TriadFit.summary()``).
"""

from __future__ import annotations

from workbench.analysis.turntable import TriadFit


def result_dict(fits: dict[str, TriadFit], full_scale: float | None = None) -> dict:
    """``result.json`` content: each fit's estimates and sigmas (SI) and its residual table."""
    out = {}
    for name, fit in fits.items():
        d = fit.to_dict()
        d["residuals"] = fit.residuals.to_dict(orient="records")
        out[name] = d
    if full_scale is not None:
        out["full_scale_rad_s"] = full_scale
    return out
