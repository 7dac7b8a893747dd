"""Run: pick a procedure, a unit grade and the simulated rig, preview the sequence, run it, see results.

The run is a detached ``workbench run`` process (see :mod:`dashboard.jobs`): reloading or
leaving the page does not stop it, and the progress shown here is read from the files the
runner writes in its folder (planned steps, the step log, result.json), never from its output.
Once a run is started the page leads with it (progress, partial plots, then its results) and
keeps the form for the next run below.
"""

import shlex

import streamlit as st

from dashboard import charts, forms, jobs, results, ui
from workbench.errors import WorkbenchError
from workbench.options import declarations

TITLE = "Run"
POLL_S = 1.0  # s between progress polls of a running run


def new_run_form() -> None:
    """Procedure, grade, rig, seed and options; the sequence preview; the start button."""
    left, right = st.columns([1, 1])
    with left:
        proc = forms.procedure_picker(key="run.procedure")
        grade = forms.grade_picker(key="run.grade")
        st.radio("Rig", ["Simulated rig (sim)"], key="run.rig",
                 help="Real rigs are driven from the command line (workbench run --rig RIG.yaml).")
        seed = int(st.number_input("Seed", value=1, min_value=0, step=1, key="run.seed"))
    with right:
        options = {}
        if proc is not None:
            st.markdown("**Options**")
            options = forms.option_inputs(proc, key="run.options")
    if proc is None or grade is None:
        return
    st.subheader("Sequence")
    try:
        seq = forms.build_sequence(proc, grade, options)
        forms.show_sequence(seq)
    except Exception as exc:  # noqa: BLE001 - a procedure's own bug must not take the page down
        ui.show_error(exc, f"sequence of {proc.NAME} for {grade.stem}")
        return
    if st.button("Start run", type="primary", key="run.start"):
        try:
            defaults = {o.name: o.default for o in declarations(proc)}  # sequence, analysis and rig options
            changed = {k: v for k, v in options.items() if v != defaults.get(k)}
            folder = jobs.start_run(proc.NAME, grade, seed=seed, options=changed,
                                      expected_s=float(seq.duration_s), n_steps=len(seq.expand()))
        except (OSError, WorkbenchError) as exc:
            ui.show_error(exc, "start run")
            return
        st.session_state["run.folder"] = str(folder)
        st.session_state["run.pick"] = folder.name
        st.rerun()


@st.fragment(run_every=POLL_S)
def live_progress(folder):
    """Progress bar and partial plots of a running run; reruns the page when the run ends."""
    status = jobs.run_status(folder)
    if status.state != "running":
        st.rerun(scope="app")
    frac = status.progress
    if status.steps_planned and status.steps_done >= status.steps_planned:
        text = f"{status.job.get('procedure')}: all {status.steps_done} steps recorded; analysing ..."
    else:
        text = (f"{status.job.get('procedure')}: {status.steps_done} of {status.steps_planned or '?'} steps recorded"
                + (f" ({100 * frac:.0f} % of rig time)" if frac is not None else ""))
    st.progress(frac if frac is not None else 0.0, text=text)
    if status.session_dir is not None:
        df = jobs.partial_samples(status.session_dir, max_points=1500)
        if df is not None and len(df):
            for what in ("gyro", "accel", "mag"):
                charts.samples_chart(df, what, height=200)


def runs_section() -> None:
    """Pick a run (the one just started by default): progress while it runs, then its results or its error."""
    st.subheader("Runs")
    runs = jobs.list_runs()
    if not runs:
        st.caption("No runs yet.")
        return
    names = [r.name for r in runs]
    if st.session_state.get("run.pick") not in names:
        st.session_state["run.pick"] = names[0]
    picked = runs[names.index(st.selectbox("Run", names, key="run.pick"))]
    try:
        status = jobs.run_status(picked)
    except WorkbenchError as exc:
        ui.show_error(exc)
        return
    command = status.job.get("command")
    if command:  # shell-quoted, as it would be typed; its user text (paths, option values) shown as typed
        st.caption(ui.md_escape(shlex.join(map(str, command))))
    if status.state == "running":
        if st.button("Stop this run", key="run.stop"):
            jobs.stop_run(picked)
            st.rerun()
        live_progress(picked)
    elif status.state == "failed":
        how = f"failed (exit code {status.exit_code})" if status.exit_code is not None else "was stopped"
        st.error(f"Run {ui.md_escape(picked.name)} {how} after {status.steps_done} of {status.steps_planned or '?'} "
                 "steps" + (f":  \n{ui.md_escape(status.error)}" if status.error else "."), icon="⚠️")
        with st.expander("Output of the run"):
            st.code(status.log or "(no output)", language=None)
    else:
        st.success(f"Run {ui.md_escape(picked.name)} finished: {status.steps_done} steps recorded.")
        st.markdown("**Results**")
        if status.result_dir is not None:
            results.show_result(status.result_dir)  # summary (lab units), warnings and figures of result.json
        else:
            st.caption("No result.json was written.")
        with st.expander("Output of the run"):
            st.code(status.log or "(no output)", language=None)
        ui.page_link("dashboard/pages/95_calibration_sets.py", "Calibration sets →")


st.title("Run a procedure")
if st.session_state.get("run.folder"):
    runs_section()
    st.divider()
    with st.expander("New run", expanded=False):
        new_run_form()
else:
    new_run_form()
    st.divider()
    runs_section()
