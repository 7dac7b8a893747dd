"""Magnetometer: pick a magnetometer session, analyse it, see hard/soft iron, heading error and figures.

Library calls only: ``procedures.magnetometer.analyze`` through ``dashboard.results``; the
numbers come from the result object, shown in lab units (µT, %, °, mrad) with their 1-sigma
("not observed" where the data cannot tell).
"""

import numpy as np
import pandas as pd
import streamlit as st

from dashboard import results, ui

TITLE = "Magnetometer"


def numbers_table(cal) -> pd.DataFrame:
    """One row per estimate: quantity, value ± sigma in lab units."""
    fit = cal.fit
    rows = [(f"hard iron {a}", ui.lab(v, "uT", s)) for a, v, s in zip("xyz", fit.bias, fit.bias_sigma)]
    off = fit.soft_iron - np.eye(3)
    rows += [(f"soft iron (I+M - I)[{i},{j}]", ui.lab(off[i, j], "%", fit.soft_iron_sigma[i, j], 3))
             for i in range(3) for j in range(3)]
    rows.append(("field norm", ui.lab(fit.field_norm_ut, "uT",
                                          None if fit.scale_fixed_by == "reference" else fit.field_norm_sigma)
                 + (" (given)" if fit.scale_fixed_by == "reference" else "")))
    if fit.dip is not None:
        rows.append(("dip", ui.lab(fit.dip, "deg", fit.dip_sigma)))
    if fit.declination is not None:
        rows.append(("declination (from the table reference)",
                     ui.lab(fit.declination, "deg", fit.declination_sigma)))
    if fit.alignment is not None:
        rows += [(f"IMU-to-mag rotation {a}", ui.lab(v, "mrad", s))
                 for a, v, s in zip("xyz", fit.alignment, fit.alignment_sigma)]
    rows.append(("sphere coverage", f"{cal.quality.coverage:.0%}"))
    if cal.heading is not None:
        rows.append((f"heading error RMS (tilt from {cal.heading.tilt_source})", ui.lab(cal.heading.rms, "deg")))
        if cal.baseline_heading is not None:
            rows.append(("heading error RMS, plain algebraic fit", ui.lab(cal.baseline_heading.rms, "deg")))
    return pd.DataFrame(rows, columns=["quantity", "value"])


st.title(TITLE)
st.caption("Hard and soft iron, field norm, dip, mag-to-IMU rotation and tilt-compensated heading error "
           "from yaw sweeps at the fixture's tilts. Record a session on the Run page (procedure 'magnetometer').")
ui.page_link("pages/20_run.py", "Run a magnetometer sequence")
result = results.result_picker("magnetometer", key="mag")
if result is not None:
    cal = result.payload
    st.subheader(f"Method: {cal.fit.method}")
    st.write(cal.choice.reason)
    st.dataframe(numbers_table(cal), hide_index=True, width="stretch")
    results.show_result(result)
