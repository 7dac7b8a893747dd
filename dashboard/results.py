"""Sessions and analysis results on the dashboard: pick a recorded session, show what was stored.

- :func:`session_dirs` / :func:`session_picker` — recorded sessions (store and dashboard runs);
- :func:`stored_result` / :func:`show_stored_result` — a session's stored result as computed then
  (summary, options, the figures drawn then);
- :func:`result_picker` — what an analysis page needs: the stored result, re-analysis on request;
- :func:`analyze_session` — ``procedure.analyze`` of a session folder, cached, storing nothing;
- :func:`store_analysis` — the same analysis stored (result and calibration set) through the gate, on request;
- :func:`show_result` / :func:`show_figures` — summary, warnings and figures of a
  :class:`ProcedureResult` or of an output folder.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import streamlit as st

from dashboard import jobs, roots
from dashboard.forms import option_inputs
from dashboard.ui import guarded, in_store, md_escape, show_error, store
from workbench import registry
from workbench.errors import WorkbenchError
from workbench.procedure import ProcedureResult


def session_dirs(procedure: str | None = None) -> dict[str, Path]:
    """Recorded session folders (store sessions and dashboard runs), label -> path, newest first."""
    out: dict[str, Path] = {}
    try:
        rows = store().list_sessions()
    except WorkbenchError as exc:
        show_error(exc, "store")
        rows = []
    for r in rows:
        if procedure is None or r.procedure == procedure:
            out[f"{r.created} · {r.procedure} · {r.serial} · {r.id[:8]}"] = Path(r.path)
    for folder in jobs.list_runs():
        d = jobs.find(folder, "session.json")
        if d is not None and d not in out.values():
            try:
                proc = json.loads((folder / jobs.JOB_FILE).read_text()).get("procedure")
            except (OSError, json.JSONDecodeError):
                continue
            if procedure is None or proc == procedure:
                out[f"run {folder.name}"] = d
    return out


def session_picker(procedure: str | None = None, key: str = "session") -> Path | None:
    """A select box over recorded sessions (of ``procedure`` if given); a path typed in also works."""
    dirs = session_dirs(procedure)
    choice = st.selectbox("Session", ["(type a folder)", *dirs], index=1 if dirs else 0, key=key)
    if choice == "(type a folder)":
        typed = st.text_input("Session folder", key=f"{key}.typed",
                              help="A folder inside the data roots (WORKBENCH_DATA_ROOTS; default the runs folder, "
                                   "the SQLite store's folder and the working directory).")
        if not typed:
            return None
        try:
            return roots.confined_folder(typed, roots.data_roots(roots.default_roots()))
        except WorkbenchError as exc:
            show_error(exc, "session folder")
            return None
    return dirs[choice]


def folder_mtime(folder: Path) -> float:
    """Newest modification time of the files directly in ``folder`` (a cache key for its contents)."""
    return max((p.stat().st_mtime for p in folder.iterdir()), default=0.0) if folder.is_dir() else 0.0


@st.cache_resource(show_spinner=False, max_entries=8)
def _analyze(procedure: str, folder: str, mtime: float, options_json: str) -> ProcedureResult:
    from workbench.session import load_session

    session = load_session(folder)
    return registry.procedure(procedure).analyze(session, **json.loads(options_json))


def analyze_session(procedure: str, folder: Path, options: Mapping | None = None) -> ProcedureResult:
    """``procedure.analyze(load_session(folder), **options)``, cached per folder version and options.

    Pure (nothing is written or stored); raises WorkbenchError for bad sessions.
    """
    return _analyze(procedure, str(folder), folder_mtime(Path(folder)), json.dumps(dict(options or {}), sort_keys=True))


def stored_result(procedure: str, folder: Path) -> dict | None:
    """The newest stored result (store row: ``result``, ``created``, ``calibration_id``) of the session in ``folder``."""
    try:
        session_id = json.loads((Path(folder) / "session.json").read_text()).get("id")
        rows = store().list_results(procedure)
    except (OSError, json.JSONDecodeError, WorkbenchError):
        return None
    return next((r for r in rows if r["session_id"] == session_id), None)


def show_stored_result(procedure: str, folder: Path, row: dict) -> None:
    """A stored result as it was computed: its summary, warnings, options and the figures drawn then."""
    from workbench.stored import option_text, stored_figures, stored_options

    doc = row["result"]
    options = stored_options(folder, procedure, doc)
    st.success(f"Stored result of {row['created']} (as computed then; nothing re-analysed)")
    st.caption("Options it was computed with: " + (", ".join(f"{k} = {option_text(v)}" for k, v in options.items())
                                                  if options else "the defaults" if options == {} else "not recorded"))
    summary = [str(s) for s in doc.get("summary", [])]
    if summary:
        st.code("\n".join(summary), language=None, wrap_lines=True)
    for w in doc.get("warnings", []):
        st.warning(str(w))
    with st.expander("result.json"):
        st.json(doc)
    pngs = stored_figures(folder, doc)
    for png in pngs:
        st.image(str(png), caption=png.stem.replace("_", " "))
    if not pngs:
        st.caption("No figures were stored with this result.")


def result_picker(procedure: str, key: str = "result") -> ProcedureResult | None:
    """What an analysis page needs: pick a session of ``procedure``; its stored result is shown as stored.

    Re-analysis of a session with a stored result is an explicit button naming the options it
    uses; a session without one (e.g. a folder typed in) is analysed with the options shown.
    Neither stores anything. Returns the ProcedureResult of that analysis (None while the stored
    result is shown, when there is no session yet or the analysis fails).
    """
    try:
        proc = registry.procedure(procedure)
    except WorkbenchError as exc:
        st.info(f"Procedure {procedure!r} is not installed yet ({exc}).")
        return None
    folder = session_picker(procedure, key=f"{key}.session")
    if folder is None:
        st.info(f"No {procedure} session yet: record one on the Run page or type a session folder.")
        return None
    row = stored_result(procedure, folder)
    if row is not None:
        show_stored_result(procedure, folder, row)
    with st.expander("Re-analyse (stores nothing)" if row is not None else "Analysis options", expanded=False):
        options = option_inputs(proc, key=f"{key}.options", stage="analysis")
        defaults = dict(getattr(proc, "DEFAULTS", {}))
        changed = {k: v for k, v in options.items() if k not in defaults or defaults[k] != v}
        text = "the defaults" + "".join(f", {k} = {json.dumps(v)}" for k, v in changed.items())
        flag = f"{key}.reanalyse.{folder}"
        if row is not None and st.button(f"Re-analyse with: {text}", key=f"{key}.reanalyse"):
            st.session_state[flag] = True
    if row is not None and not st.session_state.get(flag):
        return None  # the stored result is what the page shows
    try:
        with st.spinner(f"Analysing {folder.name} ..."):
            result = analyze_session(procedure, folder, options)
    except Exception as exc:  # noqa: BLE001 - any failure of the analysis is shown, the page stays usable
        show_error(exc, f"{procedure} on {folder}")
        return None
    st.info(f"{'Re-analysis' if row is not None else 'No stored result for this session: analysis'} of "
            f"{md_escape(folder.name)} with {text} (not stored).")
    if st.button(f"Store this analysis ({text})", key=f"{key}.store",
                 help="Stores the result and its calibration set, after the plausibility checks; "
                      "an implausible set is refused (the CLI's --force keeps it, with the failed check noted)."):
        if store_analysis(procedure, folder, options):
            st.session_state.pop(flag, None)  # the page shows the stored result from now on
    return result


def store_analysis(procedure: str, folder: Path, options: Mapping | None = None) -> bool:
    """Store ``procedure``'s analysis of the session in ``folder`` with ``options``: the session record,
    the result and its calibration set in one transaction, after the plausibility gate
    (``workbench analyze PROCEDURE FOLDER`` without ``--force``). Nothing is stored on failure,
    which is shown as one error line; returns whether it was stored."""
    from workbench.procedure import run_analysis
    from workbench.session import load_session

    try:
        with st.spinner(f"Storing the {procedure} analysis of {folder.name} ..."):
            result = run_analysis(registry.procedure(procedure), load_session(folder), dict(options or {}),
                                  store=store(), figures=False)
    except WorkbenchError as exc:
        show_error(exc, f"storing {procedure} of {folder.name}")
        return False
    cal = result.calibration
    st.success(f"Stored the {procedure} result of {md_escape(folder.name)}"
               + (f" and calibration set {cal.id}" if cal is not None else "") + ".")
    return True


def show_figures(result: ProcedureResult | Path) -> None:
    """Figures of a result: drawn by ``procedure.figures(result)``, or the PNGs of an output folder."""
    if isinstance(result, ProcedureResult):
        import matplotlib.pyplot as plt

        with guarded(f"figures of {result.procedure}", catch_all=True):
            figs = registry.procedure(result.procedure).figures(result)
            for name, fig in figs.items():
                st.markdown(f"**{name}**")
                st.pyplot(fig, clear_figure=True)
                plt.close(fig)
        return
    pngs = sorted(Path(result).rglob("figures/*.png"))
    for png in pngs:
        st.image(str(png), caption=png.stem)
    if not pngs:
        st.caption("No figures.")


def show_result(result: ProcedureResult | Path, figures: bool = True) -> None:
    """Summary lines (lab units), warnings, calibration id and figures of a result or output folder."""
    if isinstance(result, ProcedureResult):  # a re-analysis: its partial set was never stored
        summary, warnings = list(result.summary), list(result.warnings)
        cal_id = None
    else:
        rpath = next(iter(sorted(Path(result).rglob("result.json"))), None)
        doc = json.loads(rpath.read_text()) if rpath else {}
        summary = [str(s) for s in doc.get("summary", [])]
        warnings, cal_id = [str(w) for w in doc.get("warnings", [])], doc.get("calibration_id")
        if not summary and doc:
            with st.expander("result.json"):
                st.json(doc)
    if summary:
        st.code("\n".join(summary), language=None, wrap_lines=True)
    for w in warnings:
        st.warning(w)
    if cal_id and in_store(cal_id):  # name a calibration set only when the store holds it
        st.caption(f"Calibration set {cal_id}")
    if figures:
        show_figures(result)
