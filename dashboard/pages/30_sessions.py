"""Sessions: browse recorded sessions, import a file through an import profile, inspect samples by step.

Plots are min/max envelopes of at most a few thousand points (``charts.downsample``), so a
multi-hour session at hundreds of Hz stays responsive. An import is written to a temporary
folder, validated by loading it, and only then moved into place and recorded in the store.
"""

import json
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import streamlit as st

from dashboard import charts, jobs, results, roots, ui
from workbench.calset import file_sha256
from workbench.errors import WorkbenchError

TITLE = "Sessions"
MAX_POINTS = 4000  # points per plotted series (min/max envelope)


@st.cache_resource(show_spinner=False, max_entries=4)
def _load(folder: str, mtime: float):
    from workbench.session import load_session

    return load_session(folder, require_complete=False)


def load(folder: Path):
    """The session in ``folder`` (cached per folder version); raises SessionError."""
    return _load(str(folder), results.folder_mtime(Path(folder)))


def import_profiles() -> dict[str, Path]:
    """Import profiles shipped in fixtures (any ``*.yaml`` under a folder named like ``*profile*``)."""
    found = sorted(p for p in jobs.REPO.glob("fixtures/**/*.y*ml") if "profile" in str(p.parent.name))
    return {p.stem: p for p in found}


def import_upload(profile: Path, name: str, data: bytes, companions: dict[str, bytes]) -> Path:
    """Import an uploaded recording through ``profile`` into ``runs/imports/<name>``, all or nothing.

    ``companions`` are files the profile refers to next to the recording (e.g. a sections
    JSON). The importer writes into a temporary folder and validates the session; only a
    valid session is moved into place and recorded in the store.
    """
    from workbench.importer import import_file

    dest_root = roots.runs_dir() / "imports"
    dest_root.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=dest_root, prefix=".import-") as tmp:
        src = Path(tmp) / Path(name).name
        src.write_bytes(data)
        for cname, cdata in companions.items():
            (Path(tmp) / Path(cname).name).write_bytes(cdata)
        out = Path(tmp) / "session"
        try:
            session = import_file(profile, src, out)
        except WorkbenchError as exc:  # name the uploaded file, not the temporary folder
            raise type(exc)(str(exc).replace(f"{tmp}/", "uploaded ")) from None
        dest = dest_root / f"{Path(name).stem}-{session.id[:8]}"
        if dest.exists():
            raise FileExistsError(f"{dest} already exists (this recording was imported before)")
        shutil.move(str(out), dest)
    ui.store().add_session(session.id, session.unit.serial, session.unit.model, session.procedure or "import",
                               str(dest), file_sha256(dest / "samples.parquet"), len(session.steps), True)
    return dest


st.title("Sessions")
tab_browse, tab_import = st.tabs(["Browse and inspect", "Import a file"])

with tab_import:
    st.markdown("Convert a recording from another tool (CSV / Parquet) into a session with an import profile.")
    profiles = import_profiles()
    source = st.radio("Profile", ["shipped", "upload"], horizontal=True, key="imp.source")
    profile_path = None
    if source == "shipped":
        if profiles:
            profile_path = profiles[st.selectbox("Import profile", list(profiles), key="imp.profile")]
        else:
            st.caption("No import profiles in fixtures/; upload one.")
    else:
        up = st.file_uploader("Import profile (YAML)", type=["yaml", "yml"], key="imp.profile_upload")
        if up is not None:
            tmp_profile = Path(tempfile.mkdtemp(prefix="wb-profile-")) / Path(up.name).name
            tmp_profile.write_bytes(up.getvalue())
            profile_path = tmp_profile
    data_file = st.file_uploader("Recording", type=["csv", "parquet", "txt", "dat"], key="imp.data")
    companions = st.file_uploader("Companion files the profile refers to (e.g. a sections JSON)",
                                  accept_multiple_files=True, key="imp.companions") or []
    if st.button("Import", disabled=profile_path is None or data_file is None, key="imp.go"):
        try:
            dest = import_upload(profile_path, data_file.name, data_file.getvalue(),
                                 {c.name: c.getvalue() for c in companions})
            st.success(f"Imported into {dest}")
        except Exception as exc:  # noqa: BLE001 - unreadable uploads raise many types; nothing was kept
            ui.show_error(exc, f"import of {data_file.name}")

with tab_browse:
    folder = results.session_picker(key="sess.pick")
    if folder is None:
        st.info("No sessions yet.")
        st.stop()
    try:
        session = load(folder)
    except WorkbenchError as exc:
        ui.show_error(exc)
        st.stop()

    c1, c2, c3, c4 = st.columns([3, 2, 1.2, 1.6])
    c1.metric("Unit", f"{session.unit.serial}")
    c2.metric("Procedure", session.procedure or "—")
    c3.metric("Samples", f"{len(session.samples):,}")
    c4.metric("Duration", ui.format_duration(float(session.samples["t"].iloc[-1] - session.samples["t"].iloc[0])
                                                 if len(session.samples) else 0.0))
    st.caption(f"{folder} · {session.sample_rate_hz:g} Hz · site latitude {session.site.latitude_deg:.4f}° · "
               f"rig {session.rig or '—'} · model {session.unit.model or '—'}")

    steps = pd.DataFrame([{"index": s.index, "kind": s.kind, "label": s.label, "t_start_s": s.t_start,
                           "duration_s": round(s.duration, 3),
                           "table_angle_deg": round(float(np.degrees(s.table_angle)), 3),
                           "table_rate_dps": round(float(np.degrees(s.table_rate)), 4),
                           "temperature_c": s.temperature_c} for s in session.steps])
    st.subheader("Steps")
    st.dataframe(steps.rename(columns=ui.lab_label), hide_index=True, height=min(35 * (len(steps) + 1) + 3, 300))

    st.subheader("Samples")
    options = ["all steps", *[f"{s.index}: {s.kind} {s.label}".strip() for s in session.steps]]
    pick = st.selectbox("Step", options, key="sess.step")
    df = session.samples if pick == "all steps" else session.step_samples(int(pick.split(":")[0]))
    triads = [k for k, (cols, _) in charts.PLOT_UNITS.items() if all(c in df.columns for c in cols)]
    extra = [c for c in ("temp", "table_angle", "table_rate") if c in df.columns]
    shown = st.multiselect("Show", [*triads, *extra], default=triads[:2], key="sess.show")
    small = charts.downsample(df, max_points=MAX_POINTS)
    if len(small) < len(df):
        st.caption(f"{len(df):,} samples shown as a min/max envelope of {len(small):,} points.")
    for what in shown:
        charts.samples_chart(small, what)
    with st.expander("Manifest (session.json)"):
        st.json(json.loads(json.dumps(session.manifest(), default=str)))
