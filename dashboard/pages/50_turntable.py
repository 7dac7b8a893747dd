"""Turntable calibration: run a multi-position / rate / Ferraris sequence, see the coefficients.

Library calls only: the run is ``workbench run`` (``dashboard.jobs.start_run``), the analysis the
procedure's ``analyze`` (``results.result_picker``), the figures its ``figures`` (per-position
residuals before/after, compensated vs table rate, scale-factor error vs rate, turn checks).
Numbers in lab units: mg, °/h, ppm, mrad, % of full scale, each with its 1-sigma.
"""

import numpy as np
import pandas as pd
import streamlit as st

from dashboard import forms, results, ui
from workbench import units

TITLE = "Turntable calibration"
PROCEDURES = {"multiposition": "Multi-position static tumble (accel + gyro bias/g-sensitivity)",
              "rate": "Rate table (gyro scale factor, misalignment, nonlinearity, asymmetry)",
              "ferraris": "Ferraris: 6 positions + 3 turns (hand-made sessions)"}


def coefficient_table(fit) -> pd.DataFrame:
    """One row per coefficient of a TriadFit, in the lab units of ``units.QUANTITIES`` with its 1-sigma
    ('not observed' if NaN): bias, scale factor, misalignment, nonlinearity, asymmetry, g-sensitivity."""
    t, rows = fit.triad, []

    def cell(quantity: str, value: float, sigma: float) -> str:
        return units.show(t, quantity, value, sigma) if np.isfinite(sigma) else "not observed"

    for i, a in enumerate("xyz"):
        rows.append((f"bias {a}", cell("bias", fit.bias[i], fit.bias_sigma[i])))
    for i in range(3):
        for j in range(3):
            name = f"scale factor {'xyz'[i]}" if i == j else f"misalignment M{'xyz'[i]}{'xyz'[j]}"
            rows.append((name, cell("scale_factor" if i == j else "misalignment", fit.scale_misalignment[i, j],
                                    fit.scale_misalignment_sigma[i, j])))
    for i, a in enumerate("xyz"):
        if np.isfinite(fit.nonlinearity_sigma[i]):
            rows.append((f"nonlinearity {a}", cell("nonlinearity", fit.nonlinearity[i], fit.nonlinearity_sigma[i])))
        if np.isfinite(fit.asymmetry_sigma[i]):
            rows.append((f"SF asymmetry {a}", cell("scale_factor", fit.asymmetry[i], fit.asymmetry_sigma[i])))
    if fit.g_sensitivity is not None:
        for i in range(3):
            for j in range(3):
                rows.append((f"g-sensitivity G{'xyz'[i]}{'xyz'[j]}",
                             cell("g_sensitivity", fit.g_sensitivity[i, j], fit.g_sensitivity_sigma[i, j])))
    return pd.DataFrame(rows, columns=["coefficient", "estimate ± 1σ"])


def residual_table(fit, full_scale=None) -> pd.DataFrame:
    """Per-step residuals before/after compensation in lab units (mg; °/h static gyro; °/s and % FS rates)."""
    r = fit.residuals
    rate = r[["ref_x", "ref_y", "ref_z"]].abs().to_numpy().max() > 1e-3 if len(r) else False
    unit = "mg" if fit.triad == "accel" else ("deg/s" if rate else "deg/h")
    out = pd.DataFrame({"step": r["step"], "label": r["label"], "used": r["used"]})
    for when in ("before", "after"):
        worst = np.abs(r[[f"{when}_x", f"{when}_y", f"{when}_z"]].to_numpy()).max(axis=1)
        out[f"max |{when}| [{units.label(unit)}]"] = ui.lab_array(worst, unit)
        if full_scale:
            out[f"{when} [% FS]"] = worst / full_scale * 100
    if fit.triad == "accel":
        out["| |a| - g | after [mg]"] = ui.lab_array(np.abs(r["after_norm"].to_numpy()), "mg")
    return out


st.title(TITLE)
name = st.selectbox("Procedure", list(PROCEDURES), format_func=PROCEDURES.get, key="tt.proc")
tab_run, tab_result = st.tabs(["Run on the simulated rig", "Result of a session"])

with tab_run:
    forms.run_panel(name, "tt", "turntable run")

with tab_result:
    result = results.result_picker(name, key="tt.result")
    if result is not None and isinstance(result.payload, dict):
        fs = result.payload.get("full_scale")
        for triad in ("accel", "gyro"):
            fit = result.payload.get(triad)
            if fit is None:
                continue
            st.subheader(f"{triad}: coefficients")
            st.dataframe(coefficient_table(fit), hide_index=True, width="stretch")
            st.subheader(f"{triad}: residuals per step")
            st.dataframe(residual_table(fit, fs if triad == "gyro" else None), hide_index=True, width="stretch")
        turns = result.payload.get("turns")
        if turns:
            st.subheader("hand-made turns")
            st.dataframe(pd.DataFrame([{"turn": c.label, "angle [°]": np.degrees(c.angle),
                                        "closure [°]": np.degrees(c.closure),
                                        "wobble rms [°]": np.degrees(c.wobble_rms),
                                        "backward [°]": np.degrees(c.backward),
                                        "axis tilt [°]": np.degrees(c.axis_tilt),
                                        "motion before/after [°]": f"{np.degrees(c.motion_before):.3f} / "
                                                                   f"{np.degrees(c.motion_after):.3f}"}
                                       for c in turns]), hide_index=True)
        results.show_result(result)
