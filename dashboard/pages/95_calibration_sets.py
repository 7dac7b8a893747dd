"""Calibration sets: list per unit, show one, diff two versions (change in sigma), approve, download.

Coefficients are shown in the lab units of ``workbench.units.QUANTITIES`` through
``workbench.coefficients`` (the rows ``workbench sets show`` and the certificate print); the
diff is ``workbench.diff.diff_sets``: ``change_in_sigma = (new - old) / sqrt(sigma_old² +
sigma_new²)`` where both versions observed a coefficient (highlighted above 1 and 3), and
"not observed in A / B" as its own state otherwise. Downloads are produced by every exporter
in ``workbench.registry.exporters()``.
"""

import json

import numpy as np
import pandas as pd
import streamlit as st

from dashboard import auth, ui
from workbench import coefficients, registry
from workbench.diff import NOT_COMPARABLE, NOT_OBSERVED, NOT_OBSERVED_A, NOT_OBSERVED_B, diff_sets
from workbench.errors import ExportError, WorkbenchError

TITLE = "Calibration sets"
WARN_SIGMA, ALARM_SIGMA = 1.0, 3.0  # |change| in sigma highlighted orange / red


def coefficient_table(calset) -> pd.DataFrame:
    """Every coefficient of a set with its 1-sigma in lab units ('not observed' where NaN)."""
    return pd.DataFrame([{"triad": r.triad, "field": r.field, "index": str(list(r.index)), "coefficient": r.name,
                          "value": coefficients.value_text(r.value, 6), "sigma": coefficients.sigma_text(r.sigma),
                          "unit": r.unit}
                         for t in calset.triads for r in coefficients.triad_rows(calset, t)])


def noise_table(calset) -> pd.DataFrame:
    """Noise terms per triad, term and axis in lab units with their 95 % intervals ('not observed' where null)."""
    return pd.DataFrame([{"triad": r.triad, "term": r.term, "axis": r.axis,
                          "value": "not observed" if not np.isfinite(r.value) else f"{r.value:.4g}",
                          "95 % interval": coefficients.ci_text(r.ci95), "unit": r.unit}
                         for r in coefficients.noise_rows(calset)])


def diff_table(old, new) -> pd.DataFrame:
    """Rows of ``diff_sets(old, new)`` in lab units, with their state (changed / not observed in A or B)."""
    rows = []
    for r in diff_sets(old, new):
        if r.field == "(triad)" or r.state == NOT_COMPARABLE:
            rows.append({"triad": r.triad, "field": r.field, "index": "",
                         "coefficient": "(whole triad)" if r.field == "(triad)" else r.note, "state": r.state,
                         "old": "", "new": "", "σ": "", "unit": "", "change (σ)": np.nan})
            continue
        label, f = coefficients.element_unit(r.triad, r.field, r.index)
        rows.append({"triad": r.triad, "field": r.field, "index": str(list(r.index)),
                     "coefficient": coefficients.element_name(r.field, r.index), "state": r.state,
                     "old": "not observed" if r.state in (NOT_OBSERVED_A, NOT_OBSERVED) else coefficients.value_text(r.old / f, 6),
                     "new": "not observed" if r.state in (NOT_OBSERVED_B, NOT_OBSERVED) else coefficients.value_text(r.new / f, 6),
                     "σ": coefficients.value_text(r.sigma / f, 3), "unit": label, "change (σ)": r.change_in_sigma})
    return pd.DataFrame(rows)


def _highlight(value: float) -> str:
    if not np.isfinite(value):
        return "color: gray"
    if abs(value) > ALARM_SIGMA:
        return "background-color: #f8b4b4"
    return "background-color: #fde68a" if abs(value) > WARN_SIGMA else ""


def certificate_section(db, calset, version: int, stem: str) -> None:
    """Render the set's certificate on request (from the store only, as ``workbench certificate``):
    HTML and, where Chromium is installed, PDF downloads (a PDF Chromium fails to print is said beside
    the HTML). Kept for the set and its approval state."""
    from workbench.fleet.certificate import certificate_number, find_chromium, print_pdf, write_certificate

    key = (calset.id, (db.approval(calset.id) or {}).get("approved_at"))
    if st.button("Render the certificate", key="cal.cert"):
        import tempfile
        from pathlib import Path

        try:
            with st.spinner("Rendering the certificate (HTML, then PDF with Chromium) ..."), \
                    tempfile.TemporaryDirectory(prefix="workbench-cert-") as tmp:
                out = write_certificate(calset, db, Path(tmp) / "certificate.html", pdf=False)[0]
                html, pdf, pdf_note = out.read_text(), None, "No Chromium on this machine: HTML only."
                chromium = find_chromium()
                if chromium:
                    try:  # the HTML stands on its own: a PDF that fails is said, not the whole certificate
                        pdf = print_pdf(out, out.with_suffix(".pdf"), chromium).read_bytes()
                    except WorkbenchError as exc:
                        pdf_note = f"PDF not printed ({exc}): HTML only."
            st.session_state["cal.cert.doc"] = (key, html, pdf, pdf_note)
        except WorkbenchError as exc:
            ui.show_error(exc, "certificate")
    doc = st.session_state.get("cal.cert.doc")
    if not doc or doc[0] != key:
        st.caption("Rendered from the store only: coefficients with U (k = 2), approval, reference equipment, "
                   "ambient conditions, the stored figures.")
        return
    _, html, pdf, pdf_note = doc
    st.caption(f"Certificate {certificate_number(calset, version)} rendered"
               + ("" if key[1] else " (a draft: the set is not approved)") + ".")
    c1, c2 = st.columns(2)
    c1.download_button("certificate (.html)", html, file_name=f"{stem}_certificate.html", mime="text/html",
                       key="cal.cert.html")
    if pdf is not None:
        c2.download_button("certificate (.pdf)", pdf, file_name=f"{stem}_certificate.pdf", mime="application/pdf",
                           key="cal.cert.pdf")
    else:
        c2.text(pdf_note)  # names a temporary file and Chromium's own words: shown as typed


st.title("Calibration sets")
try:
    db = ui.store()
    unit_list = db.units()
except WorkbenchError as exc:
    ui.show_error(exc, "store")
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
    if st.session_state.get("cal.version.serial") != serial:  # another unit: open its newest version
        st.session_state.pop("cal.version", None)
        st.session_state["cal.version.serial"] = serial
    version = st.selectbox("Version", versions, key="cal.version")
    info = by_version[version]
    try:
        calset = db.get_set(info.id)
    except WorkbenchError as exc:
        ui.show_error(exc)
        st.stop()
    st.caption(f"Set {calset.id} · created {calset.created} · procedures {', '.join(calset.provenance.procedures)} "
               f"· software {calset.provenance.software_version}")
    st.subheader("Coefficients")
    st.dataframe(coefficient_table(calset), hide_index=True)
    if calset.noise:
        st.subheader("Noise terms")
        st.dataframe(noise_table(calset), hide_index=True)

    st.subheader("Approval")
    if info.approved_by:
        st.success(f"Approved by {ui.md_escape(info.approved_by)}.")
    else:
        signed_in = auth.operator()  # the signed-in operator approves; a name is typed only on an open 127.0.0.1
        by = signed_in or st.text_input("Approved by", key="cal.by")
        if signed_in:
            st.caption(f"Approving as {ui.md_escape(signed_in)} (signed in).")
        comment = st.text_input("Comment", key="cal.comment")
        if st.button("Approve", disabled=not by.strip(), key="cal.approve"):
            try:
                db.approve(calset.id, by.strip(), comment)
                st.rerun()
            except WorkbenchError as exc:
                ui.show_error(exc, "approve")

    st.subheader("Download")
    exporters = registry.exporters()
    if not exporters:
        st.caption("No export formats installed.")
    cols = st.columns(max(min(len(exporters), 4), 1))
    for i, (fmt, mod) in enumerate(sorted(exporters.items())):
        with cols[i % len(cols)]:
            try:
                out = registry.export_set(calset, fmt)  # a set stored before the serial rule: refused
            except ExportError as exc:  # the format cannot express this set: say why, not an alarm
                st.warning(f"{fmt} ({mod.SUFFIX}) not available: {exc}")
                continue
            except Exception as exc:  # noqa: BLE001 - one exporter's failure leaves the others usable
                ui.show_error(exc, f"export {fmt}")
                continue
            st.download_button(f"{fmt} ({mod.SUFFIX})", out.text, file_name=f"{serial}_v{version}{mod.SUFFIX}",
                               help=getattr(mod, "DESCRIPTION", fmt), key=f"cal.dl.{fmt}")
            if out.dropped:  # what the format cannot hold, folded: the buttons stay in view
                with st.expander(f"{len(out.dropped)} not expressible in {fmt}"):
                    st.caption("; ".join(out.dropped))
    with st.expander("Canonical JSON"):
        st.json(json.loads(calset.to_json()))

    st.subheader("Certificate")
    certificate_section(db, calset, version, f"{serial}_v{version}")

with tab_diff:
    if len(versions) < 2:
        st.info("Only one version: nothing to compare.")
    else:
        c1, c2 = st.columns(2)
        old_v = c1.selectbox("Old version", versions, index=1, key=f"cal.old.{serial}")
        new_v = c2.selectbox("New version", versions, index=0, key=f"cal.new.{serial}")
        try:
            table = diff_table(db.get_set(by_version[old_v].id), db.get_set(by_version[new_v].id))
        except WorkbenchError as exc:
            ui.show_error(exc, "diff")
            table = None
        if table is not None and table.empty:
            st.success("The two versions have identical coefficients.")
        elif table is not None:
            n_alarm = int((table["change (σ)"].abs() > ALARM_SIGMA).sum())
            n_changed = int(table["change (σ)"].notna().sum())
            st.caption(f"{len(table)} coefficients differ: {n_changed} observed in both versions, {n_alarm} of them "
                       f"by more than {ALARM_SIGMA:g} σ (σ = √(σA² + σB²)); {len(table) - n_changed} not "
                       "observed in one version (A = old, B = new): no change in σ is stated for those.")
            st.dataframe(table.style.map(_highlight, subset=["change (σ)"]).format({"change (σ)": "{:+.2f}"}),
                         hide_index=True)
