"""Fleet: the distribution of each coefficient across the units of a grade, outliers flagged."""

import numpy as np
import pandas as pd
import streamlit as st

from dashboard import ui
from workbench.errors import WorkbenchError
from workbench.fleet.stats import OUTLIER_Z, coefficient_stats

TITLE = "Fleet"

st.title("Fleet statistics")
st.caption("Latest calibration set of every unit of a grade; only coefficients the procedures observed. "
           f"Units whose robust z-score (median / 1.4826 MAD) exceeds {OUTLIER_Z} are flagged.")

def _display_unit(triad: str, field: str, index: tuple) -> str:
    """Lab unit of one coefficient: bias in °/h, mg or µT; scale factor ppm; misalignment mrad."""
    if field == "bias":
        return {"gyro": "deg/h", "accel": "mg", "mag": "uT"}[triad]
    if field == "scale_misalignment":
        return "ppm" if index[0] == index[1] else "mrad"
    return "1"


def _to_lab(value_si: float, unit: str) -> float:
    return float(ui.lab_array(value_si, unit))


try:
    db = ui.store()
    units = db.units()
except WorkbenchError as exc:
    ui.show_error(exc, "store")
    st.stop()

models = sorted({m for _, m in units if m})
if not models:
    st.info("No units in the store yet: run a procedure or `workbench batch` first.")
    st.stop()
grade = st.selectbox("Grade", models, key="fleet_grade")
with ui.guarded("fleet statistics"):
    sets = [c for c in (db.latest(s) for s, m in units if m == grade) if c is not None]
    rows = coefficient_stats(sets)
    st.metric("Units with a calibration set", len(sets))
    if not rows:
        st.info("Fewer than two units observe any coefficient.")
        st.stop()
    table = []
    for r in rows:
        unit = _display_unit(r.triad, r.field, r.index)
        table.append({"triad": r.triad, "field": r.field, "index": str(r.index), "unit": unit, "n": r.n,
                      **{k: float(_to_lab(v, unit)) for k, v in (("mean", r.mean), ("std", r.std),
                                                                   ("median", r.median), ("robust std", r.robust_std))},
                      "outliers": ", ".join(f"{s} (z={z:+.1f})" for s, _, z in r.outliers)})
    df = pd.DataFrame(table)
    only = st.checkbox("Only coefficients with outliers", key="fleet_only_outliers")
    st.dataframe(df[df["outliers"] != ""] if only else df, hide_index=True, width="stretch")
    pick = st.selectbox("Coefficient", [f"{r.triad} {r.field} {r.index}" for r in rows], key="fleet_coef")
    r = rows[[f"{x.triad} {x.field} {x.index}" for x in rows].index(pick)]
    unit = _display_unit(r.triad, r.field, r.index)
    values = [_to_lab(getattr(c.triads[r.triad].model, r.field)[r.index], unit) for c in sets if r.triad in c.triads]
    counts, edges = np.histogram(values, bins=min(20, max(3, len(values) // 2)))
    st.bar_chart(pd.DataFrame({"units": counts}, index=np.round(0.5 * (edges[1:] + edges[:-1]), 4)),
                 x_label=f"{pick} ({unit})", y_label="units")
