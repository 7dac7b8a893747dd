"""Calibration sets: list per unit, show one, diff two versions (change in sigma), approve, download.

Coefficients are shown in lab units (``workbench.units.DISPLAY``: bias in °/h, mg, µT; scale
factor and misalignment in ppm); the diff is ``workbench.diff.diff_sets`` with
``change_in_sigma = (new - old) / sqrt(sigma_old² + sigma_new²)`` highlighted above 1 and 3.
Downloads are produced by every exporter in ``workbench.registry.exporters()``.
"""

import json

import numpy as np
import pandas as pd
import streamlit as st

from dashboard import common
from workbench import registry, units
from workbench.diff import diff_sets
from workbench.errors import ExportError, WorkbenchError

TITLE = "Calibration sets"
FIELD_UNITS = {"scale_misalignment": "ppm", "nonlinearity": None, "g_sensitivity": None}
WARN_SIGMA, ALARM_SIGMA = 1.0, 3.0  # |change| in sigma highlighted orange / red


def field_unit(triad: str, field: str) -> str | None:
    """Lab unit a coefficient is shown in (None: shown in SI)."""
    if field == "bias":
        return units.DISPLAY.get(triad, {}).get("bias")
    return FIELD_UNITS.get(field)


def show_value(triad: str, field: str, value: float) -> str:
    unit = field_unit(triad, field)
    if value is None or not np.isfinite(value):
        return "—"
    return f"{units.to_unit(value, unit):.6g}" if unit else f"{value:.6g}"


def coefficient_table(calset) -> pd.DataFrame:
    """Every coefficient of a set with its sigma in lab units (sigma 'not observed' where NaN)."""
    rows = []
    for triad, tc in calset.triads.items():
        for field in ("bias", "scale_misalignment", "nonlinearity", "g_sensitivity"):
            value = getattr(tc.model, field)
            if value is None or (field == "nonlinearity" and not np.any(value) and field not in tc.sigma):
                continue
            sigma = tc.sigma_of(field)
            unit = field_unit(triad, field)
            for idx in np.ndindex(value.shape):
                rows.append({"triad": triad, "field": field, "index": str(list(idx)),
                             "value": show_value(triad, field, float(value[idx])),
                             "sigma": show_value(triad, field, float(sigma[idx])) if np.isfinite(sigma[idx])
                             else "not observed",
                             "unit": units.label(unit) if unit else "SI"})
    return pd.DataFrame(rows)


def noise_table(calset) -> pd.DataFrame:
    """Noise terms per triad and axis (SI; 'not observed' where null)."""
    rows = []
    for triad, terms in calset.noise.items():
        for term in terms:
            v = calset.noise_term(triad, term)
            rows.append({"triad": triad, "term": term,
                         **{ax: ("not observed" if not np.isfinite(x) else f"{x:.4g}") for ax, x in zip("xyz", v)}})
    return pd.DataFrame(rows)


def diff_table(old, new) -> pd.DataFrame:
    """Rows of ``diff_sets(old, new)`` in lab units."""
    rows = []
    for r in diff_sets(old, new):
        unit = field_unit(r.triad, r.field)
        rows.append({"triad": r.triad, "field": r.field, "index": str(list(r.index)),
                     "old": show_value(r.triad, r.field, r.old), "new": show_value(r.triad, r.field, r.new),
                     "sigma": show_value(r.triad, r.field, r.sigma), "unit": units.label(unit) if unit else "SI",
                     "change (σ)": r.change_in_sigma})
    return pd.DataFrame(rows)


def _highlight(value: float) -> str:
    if not np.isfinite(value):
        return "color: gray"
    if abs(value) > ALARM_SIGMA:
        return "background-color: #f8b4b4"
    return "background-color: #fde68a" if abs(value) > WARN_SIGMA else ""


st.title("Calibration sets")
try:
    db = common.store()
    unit_list = db.units()
except WorkbenchError as exc:
    common.show_error(exc, "store")
    st.stop()
if not unit_list:
    st.info("No units in the store yet.")
    st.stop()

serial = st.selectbox("Unit", [s for s, _ in unit_list],
                      format_func=lambda s: f"{s} ({dict(unit_list)[s] or 'model unknown'})", key="cal.unit")
history = db.history(serial)
if not history:
    st.info(f"Unit {serial} has no calibration set yet.")
    st.stop()
st.dataframe(pd.DataFrame([{"version": h.version, "created": h.created, "procedures": ", ".join(h.procedures),
                            "approved by": h.approved_by or "—", "id": h.id} for h in history]), hide_index=True)
by_version = {h.version: h for h in history}
versions = list(by_version)

tab_show, tab_diff = st.tabs(["Show, approve, download", "Diff two versions"])
with tab_show:
    version = st.selectbox("Version", versions, key="cal.version")
    info = by_version[version]
    try:
        calset = db.get_set(info.id)
    except WorkbenchError as exc:
        common.show_error(exc)
        st.stop()
    st.caption(f"Set {calset.id} · created {calset.created} · procedures {', '.join(calset.provenance.procedures)} "
               f"· software {calset.provenance.software_version}")
    st.subheader("Coefficients")
    st.dataframe(coefficient_table(calset), hide_index=True)
    if calset.noise:
        st.subheader("Noise terms (SI)")
        st.dataframe(noise_table(calset), hide_index=True)

    st.subheader("Approval")
    if info.approved_by:
        st.success(f"Approved by {info.approved_by}.")
    else:
        by = st.text_input("Approved by", key="cal.by")
        comment = st.text_input("Comment", key="cal.comment")
        if st.button("Approve", disabled=not by.strip(), key="cal.approve"):
            try:
                db.approve(calset.id, by.strip(), comment)
                st.rerun()
            except WorkbenchError as exc:
                common.show_error(exc, "approve")

    st.subheader("Download")
    exporters = registry.exporters()
    if not exporters:
        st.caption("No export formats installed.")
    cols = st.columns(max(min(len(exporters), 4), 1))
    for i, (fmt, mod) in enumerate(sorted(exporters.items())):
        with cols[i % len(cols)]:
            try:
                out = mod.export(calset)
            except ExportError as exc:  # the format cannot express this set: say why, not an alarm
                st.warning(f"{fmt} ({mod.SUFFIX}) not available: {exc}")
                continue
            except Exception as exc:  # noqa: BLE001 - one exporter's failure leaves the others usable
                common.show_error(exc, f"export {fmt}")
                continue
            st.download_button(f"{fmt} ({mod.SUFFIX})", out.text, file_name=f"{serial}_v{version}{mod.SUFFIX}",
                               help=getattr(mod, "DESCRIPTION", fmt), key=f"cal.dl.{fmt}")
            if out.dropped:
                st.caption("Not expressible: " + "; ".join(out.dropped))
    with st.expander("Canonical JSON"):
        st.json(json.loads(calset.to_json()))

with tab_diff:
    if len(versions) < 2:
        st.info("Only one version: nothing to compare.")
    else:
        c1, c2 = st.columns(2)
        old_v = c1.selectbox("Old version", versions, index=1, key="cal.old")
        new_v = c2.selectbox("New version", versions, index=0, key="cal.new")
        try:
            table = diff_table(db.get_set(by_version[old_v].id), db.get_set(by_version[new_v].id))
        except WorkbenchError as exc:
            common.show_error(exc, "diff")
            table = None
        if table is not None and table.empty:
            st.success("The two versions have identical coefficients.")
        elif table is not None:
            n_alarm = int((table["change (σ)"].abs() > ALARM_SIGMA).sum())
            st.caption(f"{len(table)} coefficients differ; {n_alarm} by more than {ALARM_SIGMA:g} σ "
                       f"(σ = √(σ_old² + σ_new²); gray = not observed).")
            st.dataframe(table.style.map(_highlight, subset=["change (σ)"]).format({"change (σ)": "{:+.2f}"}),
                         hide_index=True)
