"""Run: pick a procedure, a unit grade and the simulated rig, preview the sequence, run it, see results.

The run is a detached ``workbench run`` process (see ``dashboard.common.start_run``): reloading
or leaving the page does not stop it, and the progress shown here is read from its folder.
Once a run is started the page leads with it (progress, partial plots, then its results) and
keeps the form for the next run below.
"""

import streamlit as st

from dashboard import common
from workbench.errors import WorkbenchError

TITLE = "Run"
POLL_S = 1.0  # s between progress polls of a running run


def new_run_form() -> None:
    """Procedure, grade, rig, seed and options; the sequence preview; the start button."""
    left, right = st.columns([1, 1])
    with left:
        proc = common.procedure_picker(key="run.procedure")
        grade = common.grade_picker(key="run.grade")
        st.radio("Rig", ["Simulated rig (sim)"], key="run.rig",
                 help="Real rigs are driven from the command line (workbench run --rig RIG.yaml).")
        seed = int(st.number_input("Seed", value=1, min_value=0, step=1, key="run.seed"))
    with right:
        options = {}
        if proc is not None:
            st.markdown("**Options**")
            options = common.option_inputs(proc, key="run.options")
    if proc is None or grade is None:
        return
    st.subheader("Sequence")
    try:
        seq = common.build_sequence(proc, grade, options)
        common.show_sequence(seq)
    except Exception as exc:  # noqa: BLE001 - a procedure's own bug must not take the page down
        common.show_error(exc, f"sequence of {proc.NAME} for {grade.stem}")
        return
    if st.button("Start run", type="primary", key="run.start"):
        try:
            changed = {k: v for k, v in options.items() if v != proc.DEFAULTS.get(k)}
            folder = common.start_run(proc.NAME, grade, seed=seed, options=changed,
                                      expected_s=float(seq.duration_s), n_steps=len(seq.expand()))
        except (OSError, WorkbenchError) as exc:
            common.show_error(exc, "start run")
            return
        st.session_state["run.folder"] = str(folder)
        st.session_state["run.pick"] = folder.name
        st.rerun()


@st.fragment(run_every=POLL_S)
def live_progress(folder):
    """Progress bar and partial plots of a running run; reruns the page when the run ends."""
    status = common.run_status(folder)
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
        df = common.partial_samples(status.session_dir, max_points=1500)
        if df is not None and len(df):
            for what in ("gyro", "accel", "mag"):
                common.samples_chart(df, what, height=200)


def runs_section() -> None:
    """Pick a run (the one just started by default): progress while it runs, then its results or its error."""
    st.subheader("Runs")
    runs = common.list_runs()
    if not runs:
        st.caption("No runs yet.")
        return
    names = [r.name for r in runs]
    if st.session_state.get("run.pick") not in names:
        st.session_state["run.pick"] = names[0]
    picked = runs[names.index(st.selectbox("Run", names, key="run.pick"))]
    try:
        status = common.run_status(picked)
    except WorkbenchError as exc:
        common.show_error(exc)
        return
    st.caption(f"`{' '.join(status.job.get('command', []))}`")
    if status.state == "running":
        if st.button("Stop this run", key="run.stop"):
            common.stop_run(picked)
            st.rerun()
        live_progress(picked)
    elif status.state == "failed":
        how = f"failed (exit code {status.exit_code})" if status.exit_code is not None else "was stopped"
        st.error(f"Run {picked.name} {how}. Last lines of its log:", icon="⚠️")
        st.code(status.log or "(empty log)", language=None)
    else:
        st.success(f"Run {picked.name} finished: {status.steps_done} steps recorded.")
        st.markdown("**Results**")
        st.code(common.run_summary(status.log) or "(no summary)", language=None)  # the CLI's, in lab units
        if status.result_dir is not None:
            common.show_result(status.result_dir)
        with st.expander("Full log"):
            st.code(status.log or "(empty log)", language=None)
        common.page_link("dashboard/pages/95_calibration_sets.py", "Calibration sets →")


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
