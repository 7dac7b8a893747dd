"""Sessions: browse recorded sessions, import a recording through an import profile, inspect samples by step.

A recording is one uploaded file, the stream files of a multi-stream profile (``streams:``), or a data
folder inside the dashboard's data roots (:mod:`dashboard.roots`), imported by the CLI's importer.

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


def _store_import(profile: Path, data: Path, name: str, shown: dict[str, str]) -> Path:
    """Import ``data`` (a file, or a folder for a profile with ``streams``) through ``profile`` into
    ``runs/imports/<name>-<id>``, all or nothing, with the CLI's importer (:func:`workbench.importer.import_file`).

    The session is written into a temporary folder and validated by loading it; only then is it moved
    into place and recorded in the store. ``shown`` maps paths in error messages to what the user knows
    them as (an upload's temporary folder to "uploaded")."""
    from workbench.importer import import_file

    dest_root = roots.runs_dir() / "imports"
    dest_root.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=dest_root, prefix=".import-") as tmp:
        out = Path(tmp) / "session"
        try:
            session = import_file(profile, data, out)
        except WorkbenchError as exc:  # name the user's file or folder, not the temporary folder
            text = str(exc)
            for path, label in {**shown, str(profile): profile.name}.items():
                text = text.replace(path, label)
            raise type(exc)(text) from None
        dest = dest_root / f"{name}-{session.id[:8]}"
        if dest.exists():
            raise FileExistsError(f"{dest} already exists (this recording was imported before)")
        shutil.move(str(out), dest)
    ui.store().add_session(session.id, session.unit.serial, session.unit.model, session.procedure or "import",
                           str(dest), file_sha256(dest / "samples.parquet"), len(session.steps), True)
    return dest


def stream_files(profile: Path) -> list[str] | None:
    """The files a profile with ``streams`` reads from its data folder (None: a single-file profile)."""
    from workbench.importers.profile import load_profile

    prof = load_profile(profile)
    return [str(spec["file"]) for spec in prof["streams"].values()] if "streams" in prof else None


def import_upload(profile: Path, files: dict[str, bytes], companions: dict[str, bytes]) -> Path:
    """Import an uploaded recording through ``profile`` into ``runs/imports/``, all or nothing.

    ``files``: the recording, one file, or for a profile with ``streams`` its stream files (named as
    the profile's ``file`` entries), which become the data folder. ``companions`` are files the
    profile refers to next to the recording (e.g. a sections JSON). Upload names are single path
    components (:func:`workbench.confine.safe_component`); nothing outside the temporary folder is read.
    """
    from workbench.confine import safe_component

    if not files:
        raise WorkbenchError("recording: no file uploaded")
    streams = stream_files(profile)
    names = [safe_component(Path(n).name, "uploaded file") for n in files]
    if streams is None and len(files) > 1:
        raise WorkbenchError(f"{profile.name}: reads one file, {len(files)} uploaded ({', '.join(names)}); "
                             "a profile with streams: reads several")
    dest_root = roots.runs_dir() / "imports"
    dest_root.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=dest_root, prefix=".upload-") as tmp:
        folder = Path(tmp) / "recording"
        folder.mkdir()
        for n, data in zip(names, files.values()):
            (folder / n).write_bytes(data)
        for cname, cdata in companions.items():
            (folder / safe_component(Path(cname).name, "companion file")).write_bytes(cdata)
        data_path = folder if streams is not None else folder / names[0]
        name = Path(profile).stem if streams is not None else Path(names[0]).stem
        return _store_import(profile, data_path, name, {f"{folder}/": "uploaded ", str(folder): "uploaded files"})


def import_folder(profile: Path, typed: str) -> Path:
    """Import the recording in the data folder ``typed`` (confined to the dashboard's data roots,
    :mod:`dashboard.roots`) through ``profile``, as ``workbench import PROFILE FOLDER`` does."""
    folder = roots.confined_folder(typed, roots.data_roots(roots.default_roots()))
    if not folder.is_dir():
        raise WorkbenchError(f"{typed}: not a folder")
    return _store_import(profile, folder, folder.name, {})


def show_in_browse(dest: Path) -> None:
    """Pick the session just imported into ``dest`` in the Browse tab's session box (drawn later in this run)."""
    label = next((k for k, v in results.session_dirs().items() if Path(v) == Path(dest)), None)
    if label is not None:
        st.session_state["sess.pick"] = label


st.title("Sessions")
tab_browse, tab_import = st.tabs(["Browse and inspect", "Import a recording"])

with tab_import:
    st.markdown("Convert a recording from another tool (CSV / Parquet, one file or one file per stream) into a "
                "session with an import profile.")
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
    streams = None
    if profile_path is not None:
        try:
            streams = stream_files(profile_path)
        except WorkbenchError as exc:
            ui.show_error(exc, "import profile")
            profile_path = None
    if streams is not None:
        st.caption(f"This profile reads {len(streams)} streams from a data folder: {', '.join(streams)}.")
    where = st.radio("Recording", ["upload", "data folder"], horizontal=True, key="imp.from")
    if where == "upload":
        data_files = st.file_uploader("Recording file(s): one file, or every stream file of a multi-stream profile",
                                      type=["csv", "parquet", "txt", "dat"], accept_multiple_files=True,
                                      key="imp.data") or []
        companions = st.file_uploader("Companion files the profile refers to (e.g. a sections JSON)",
                                      accept_multiple_files=True, key="imp.companions") or []
        ready, what = bool(data_files), ", ".join(f.name for f in data_files)
    else:
        typed = st.text_input("Data folder (inside the dashboard's data roots)", key="imp.folder")
        ready, what = bool(typed.strip()), typed
    if st.button("Import", disabled=profile_path is None or not ready, key="imp.go"):
        try:
            if where == "upload":
                dest = import_upload(profile_path, {f.name: f.getvalue() for f in data_files},
                                     {c.name: c.getvalue() for c in companions})
            else:
                dest = import_folder(profile_path, typed)
            st.success(f"Imported into {dest}")
            show_in_browse(dest)
        except Exception as exc:  # noqa: BLE001 - unreadable uploads raise many types; nothing was kept
            ui.show_error(exc, f"import of {what}")

with tab_browse:
    folder = results.session_picker(key="sess.pick")
    if folder is None:
        st.info("Pick a session above, or type its folder." if results.session_dirs() else "No sessions yet.")
        st.stop()
    try:
        session = load(folder)
    except WorkbenchError as exc:
        ui.show_error(exc)
        st.stop()

    c1, c2, c3, c4 = st.columns([3, 2, 1.2, 1.6])
    ui.plain_field(c1, "Unit", session.unit.serial)  # a user's serial: whole, never as markup
    ui.plain_field(c2, "Procedure", session.procedure or "—")
    c3.metric("Samples", f"{len(session.samples):,}")
    c4.metric("Duration", ui.format_duration(float(session.samples["t"].iloc[-1] - session.samples["t"].iloc[0])
                                                 if len(session.samples) else 0.0))
    st.caption(f"{ui.md_escape(folder)} · {session.sample_rate_hz:g} Hz · site latitude "
               f"{session.site.latitude_deg:.4f}° · rig {ui.md_escape(session.rig or '—')} · "
               f"model {ui.md_escape(session.unit.model or '—')}")

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
