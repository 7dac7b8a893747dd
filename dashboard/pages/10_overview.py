"""Overview: units in the store, their latest calibration sets, recent sessions and runs, status."""

import pandas as pd
import streamlit as st

from dashboard import jobs, ui
from workbench import registry
from workbench.errors import WorkbenchError
from workbench.store import default_url, redact_url

TITLE = "Overview"

st.title("Calibration workbench")
st.caption(f"Store: {ui.md_escape(redact_url(default_url()))}")  # a path holding ` or * shown as typed

try:
    db = ui.store()
    units, sets, sessions = db.units(), db.list_sets(), db.list_sessions()
except WorkbenchError as exc:
    ui.show_error(exc, "store")
    st.stop()

runs = [jobs.run_status(f) for f in jobs.list_runs()]
running = [r for r in runs if r.state == "running"]
c1, c2, c3, c4 = st.columns(4)
c1.metric("Units", len(units))
c2.metric("Calibration sets", len(sets))
c3.metric("Sessions", len(sessions))
c4.metric("Runs in progress", len(running))

st.subheader("Units and their latest calibration set")
latest: dict[str, object] = {}
for s in sets:  # newest first: the first seen per serial is the latest
    latest.setdefault(s.serial, s)
rows = []
for serial, model in units:
    s = latest.get(serial)
    rows.append({"serial": serial, "model": model, "latest version": getattr(s, "version", None),
                 "created": getattr(s, "created", ""), "procedures": ", ".join(getattr(s, "procedures", ())),
                 "status": ("approved by " + s.approved_by) if s is not None and s.approved_by else
                 ("awaiting approval" if s is not None else "no calibration yet")})
if rows:
    st.dataframe(pd.DataFrame(rows), hide_index=True)
else:
    st.info("No units yet: record a session on the Run page or import one on the Sessions page.")

st.subheader("Recent sessions")
if sessions:
    st.dataframe(pd.DataFrame([{"created": r.created, "procedure": r.procedure, "serial": r.serial,
                                "steps": r.n_steps, "status": "complete" if r.complete else "incomplete",
                                "folder": r.path} for r in sessions[:20]]), hide_index=True)
else:
    st.caption("No sessions in the store.")

if runs:
    st.subheader("Dashboard runs")
    st.dataframe(pd.DataFrame([{"run": r.folder.name, "procedure": r.job.get("procedure"), "state": r.state,
                                "progress": None if r.progress is None else round(100 * r.progress),
                                "steps recorded": r.steps_done} for r in runs[:20]]), hide_index=True,
                 column_config={"progress": st.column_config.ProgressColumn("progress", min_value=0,
                                                                            max_value=100, format="%d %%")})

st.subheader("Installed")
procs = registry.procedures()
st.write("Procedures: " + (", ".join(f"`{n}`" for n in sorted(procs)) or "none yet"))
st.write("Export formats: " + (", ".join(f"`{n}`" for n in sorted(registry.exporters())) or "none yet"))
