"""Thermal sweeps: analyse a thermal session, see bias and scale factor vs temperature, export.

Library calls only: ``results.result_picker`` runs ``procedures/thermal.py``'s analysis; the
tables read the :class:`~workbench.analysis.thermal.ThermalResult` in lab units (°/s, mg,
ppm); the figures of one chosen quantity are drawn by ``workbench.plots.thermal``; exports go
through the registry.
"""

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import streamlit as st

from dashboard import results, ui
from workbench import registry
from workbench.plots.thermal import display_unit, order_figure, quantity_figure, residual_figure

TITLE = "Thermal"

st.title("Thermal sweeps")
st.caption("Bias and scale factor against the unit's own temperature, polynomial order by cross-validation, "
           "up/down hysteresis. Record a `thermal` session on the Run page.")
ui.page_link("pages/20_run.py", "Run a thermal profile")

result = results.result_picker("thermal", key="thermal")
if result is not None:
    r = result.payload
    c1, c2, c3 = st.columns(3)
    c1.metric("Source", r.source)
    c2.metric("Temperature range", f"{r.t_min_c:.1f} .. {r.t_max_c:.1f} °C")
    c3.metric("Reference temperature", f"{r.t_ref_c:g} °C")
    rows = []
    for q, f in r.fits.items():
        unit = display_unit(q)
        for ax in range(3):
            rows.append({"quantity": q, "axis": "xyz"[ax], "order": int(f.orders[ax]),
                         "held-out RMS": ui.lab(f.cv_rms_chosen[ax], unit),
                         "hysteresis (up - down)": ui.lab(f.hysteresis[ax], unit, f.hysteresis_sigma[ax]),
                         "hysteresis modelled": bool(f.hysteresis_modelled[ax])})
    st.subheader("Models")
    st.dataframe(pd.DataFrame(rows), hide_index=True, width="stretch")
    st.subheader("Held-out RMS residual per polynomial order")
    for q, f in r.fits.items():
        unit = display_unit(q)
        table = pd.DataFrame(ui.lab_array(f.cv_rms, unit), columns=list("xyz"),
                             index=pd.Index(f.cv_orders, name="order"))
        st.markdown(f"**{q}** ({unit}; blank = too few temperatures)")
        st.dataframe(table.replace({np.nan: None}), width="stretch")
    results.show_result(result, figures=False)
    quantity = st.selectbox("Figures of", list(r.fits), key="thermal.figures")
    fit = r.fits[quantity]
    for name, draw in (("fit", quantity_figure), ("residuals after compensation", residual_figure),
                       ("cross-validation", order_figure)):
        st.markdown(f"**{quantity}: {name}**")
        fig = draw(fit)
        st.pyplot(fig, clear_figure=True)
        plt.close(fig)
    if result.calibration is not None:
        st.subheader("Export")
        fmt = st.selectbox("Format", ["px4", "ardupilot", "c-header", "json"], key="thermal.export")
        with ui.guarded("export", catch_all=True):
            mod = registry.exporter(fmt)
            exp = registry.export_set(result.calibration, fmt)
            for line in exp.dropped:
                st.warning(f"dropped: {line}")
            st.download_button(f"Download {mod.SUFFIX}", exp.text, file_name=f"thermal{mod.SUFFIX}")
            st.code(exp.text[:4000], language=None)
