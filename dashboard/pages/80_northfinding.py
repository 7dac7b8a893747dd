"""North-finding: run a maytagging / Earth-rate / redundant / carousel sequence, see the azimuth.

Library calls only: the run is ``workbench run`` (``dashboard.jobs.start_run``), the analysis the
procedure's ``analyze`` (``results.result_picker``), the figures its ``figures``; several
sessions are compared with ``northfinding.sequence_table`` / ``pairing_table`` (thesis tables
4.3, 4.4). Numbers in lab units (°, mrad, °/h), achieved beside theoretical.
"""

import numpy as np
import pandas as pd
import streamlit as st

from dashboard import forms, results, ui
from workbench import registry

TITLE = "North-finding"
PROCEDURES = {"maytagging": "Maytagging (±180°, thesis seq. 1-7)", "earth-rate": "Earth-rate sweep (seq. 0)",
              "redundant": "Redundant configuration (45° steps, seq. 8-12)", "carousel": "Carousel (continuous)"}


def numbers(result) -> pd.DataFrame:
    """Achieved and theoretical figures of one result (lab units)."""
    r, th = result.result, result.result["theory"]
    rows = [("azimuth of body x at table zero", f"{r['azimuth_deg']:.4f} ± {r['azimuth_sigma_mrad'] * 0.18 / np.pi:.2g}°",
             f"1σ = {r['azimuth_sigma_mrad']:.3g} mrad"),
            (f"per-{r['units']} std", f"{r['pair_std_mrad']:.3g} mrad" if r["pair_std_mrad"] is not None else "—",
             f"theory: ARW {th['arw_pair_sigma_mrad'] or float('nan'):.3g} mrad, "
             f"Allan {th['allan_pair_sigma_mrad'] or float('nan'):.3g} mrad ({th['source']})"),
            ("horizontal Earth rate", ui.lab(r["earth_rate_amplitude"] if r["earth_rate_amplitude"] is not None
                                                 else np.nan, "deg/h", r["earth_rate_amplitude_sigma"]),
             f"Ω_e cos(lat) = {ui.lab(r['earth_rate_expected'], 'deg/h')}")]
    for axis, b, s in zip("xyz", r["gyro_bias"], r["gyro_bias_sigma"]):
        rows.append((f"gyro bias {axis}", ui.lab(np.nan if b is None else b, "deg/h",
                                                     None if s is None else s), ""))
    if "azimuth_error_mrad" in r:
        rows.append(("error against the table's known zero", f"{r['azimuth_error_mrad']:+.3g} mrad", ""))
    return pd.DataFrame(rows, columns=["quantity", "achieved", "reference"])


st.title("North-finding")
name = st.selectbox("Procedure", list(PROCEDURES), format_func=PROCEDURES.get, key="nf.proc")
tab_run, tab_result, tab_compare = st.tabs(["Run", "Result", "Compare sessions"])

with tab_run:
    def _applies(spec) -> None:
        proc = registry.procedure(name)
        if hasattr(proc, "applies") and not proc.applies(spec):
            st.warning(f"{spec.name}: the gyros do not resolve the Earth rate (pair 1σ > 0.1 rad)")

    forms.run_panel(name, "nf", "north-finding run", _applies)

with tab_result:
    result = results.result_picker(name, key="nf.result")
    if result is not None:
        st.dataframe(numbers(result), hide_index=True, width="stretch")
        results.show_result(result)

with tab_compare:
    st.markdown("Several sessions of the same procedure: mean per session and repeatability "
                "(thesis table 4.3 and Fig. 4.14-4.15; for the redundant configuration table 4.4).")
    dirs = results.session_dirs(name)
    chosen = st.multiselect("Sessions", list(dirs), key="nf.compare")
    if len(chosen) >= 2:
        with ui.guarded("comparison", catch_all=True):
            from workbench.analysis import northfinding as nfm
            from workbench.plots.northfinding import repeatability_figure

            payloads = [results.analyze_session(name, dirs[c]).payload for c in chosen]
            rows = nfm.sequence_table(payloads, [str(i + 1) for i in range(len(payloads))])
            st.dataframe(pd.DataFrame(rows), hide_index=True)
            st.pyplot(repeatability_figure(rows), clear_figure=True)
            if name == "redundant":
                st.dataframe(pd.DataFrame(nfm.pairing_table(payloads)), hide_index=True)
