"""Navigation: replay a session through the ZUPT alignment, the AHRS or a road filter, raw vs calibrated.

Library calls only: runs are ``workbench run`` (``dashboard.jobs.start_run``; on the simulated rig it
calibrates the unit first), the analysis is the procedure's ``analyze`` with a calibration set
from the store, the figures its ``figures``. Numbers in lab units (°, mm/s, °/h), raw beside
calibrated.
"""

import pandas as pd
import streamlit as st

from dashboard import forms, jobs, results, ui
from dashboard.land_navigation import ROAD, land_navigation_section

TITLE = "Navigation"
PROCEDURES = {"zupt-alignment": "ZUPT fine alignment (thesis ch. 3)", "ahrs-table": "AHRS on the table (paper 004)",
              "lns-dead-reckoning": "AXD-LNS odometer dead reckoning on the road (thesis ch. 2)",
              "land-ins": "Land INS with NHC, ZUPT and ZARUPT on the road (paper 001)"}


def numbers(result) -> pd.DataFrame:
    """Raw and calibrated figures of a zupt-alignment or ahrs-table result, lab units."""
    rows = []
    stat = "RMS" if result.procedure == "ahrs-table" else "worst position, final"
    for key, label in (("roll_error_deg", "roll error"), ("pitch_error_deg", "pitch error"),
                       ("heading_error_deg", "heading error")):
        rows.append((f"{label} ({stat})", *(f"{result.result[m][key]:+.3f} °" for m in ("raw", "calibrated"))))
    v = [result.result[m]["velocity_error_mps"] for m in ("raw", "calibrated")]
    rows.append(("NED velocity at the end", *("—" if x is None else f"{x * 1e3:.2f} mm/s" for x in v)))
    c = [result.result[m]["convergence_time_s"] for m in ("raw", "calibrated")]
    rows.append(("convergence time", *("never" if x is None else f"{x:.0f} s" for x in c)))
    for i, axis in enumerate("xyz"):
        rows.append((f"gyro-bias error {axis}", *(ui.lab(result.result[m]["gyro_bias_error"][i], "deg/h",
                                                             result.result[m]["gyro_bias_sigma"][i])
                                                  for m in ("raw", "calibrated"))))
    return pd.DataFrame(rows, columns=["quantity", "raw", "calibrated"])


st.title("Navigation filters")
name = st.selectbox("Procedure", list(PROCEDURES), format_func=PROCEDURES.get, key="nav.proc")
tab_run, tab_result, tab_runs = st.tabs(["Run", "Analyse a session", "Finished runs"])

with tab_run:
    st.caption("On the simulated rig the run first calibrates the unit with the calibration procedures, "
               "then records and analyses the validation sequence.")
    forms.run_panel(name, "nav", "navigation run")

with tab_result:
    folder = results.session_picker(name, key="nav.session")
    sets = []
    with ui.guarded("store"):
        sets = ui.store().list_sets()
    labels = {f"{s.serial} v{s.version} · {s.created} · {s.id[:8]}": s.id for s in sets}
    choice = st.selectbox("Calibration set", list(labels) or ["(no set in the store)"], key="nav.set")
    force = st.checkbox("Use a set of another unit (force)", key="nav.force")
    if folder is not None and choice in labels and st.button("Analyse", key="nav.analyse"):
        with ui.guarded(f"{name} on {folder}", catch_all=True):
            from workbench import registry
            from workbench.session import load_session

            with st.spinner("Replaying the session through the filters ..."):
                result = registry.procedure(name).analyze(
                    load_session(folder), calibration=ui.store().get_set(labels[choice]), force=force)
            if name in ROAD:
                ROAD[name](result.result)
            else:
                st.dataframe(numbers(result), hide_index=True, width="stretch")
            results.show_result(result)

with tab_runs:
    runs = [f for f in jobs.list_runs() if jobs.run_status(f).job.get("procedure") == name]
    if not runs:
        st.info(f"No {name} run yet: start one in the Run tab.")
    else:
        pick = st.selectbox("Run", [r.name for r in runs], key="nav.runpick")
        results.show_result(next(r for r in runs if r.name == pick))

land_navigation_section()
