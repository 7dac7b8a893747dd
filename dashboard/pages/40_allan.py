"""Allan variance: record a static hold on the simulated rig (or pick a recorded session), then show
the ADEV figure with its 95 % bands and the IEEE 952 noise terms in lab units.

Everything is computed by the library (``procedures/allan.py``); this page only asks and shows.
"""

import pandas as pd
import streamlit as st

from dashboard import forms, results, ui
from workbench.registry import procedure

TITLE = "Allan deviation"
PROC = procedure("allan")


def _simulated():
    """Grade, duration, temperature and seed; records in memory and analyses."""
    from workbench.jobs import simulate

    left, right = st.columns(2)
    with left:
        grade = forms.grade_picker(key="allan.grade")
        seed = int(st.number_input("Seed", value=1, min_value=0, step=1, key="allan.seed"))
    with right:
        minutes = st.number_input("Hold duration (min)", value=30.0, min_value=2.0, max_value=720.0, step=10.0,
                                  key="allan.minutes")
        temperature = st.number_input("Chamber setpoint (°C)", value=25.0, min_value=-40.0, max_value=85.0,
                                      key="allan.temp")
        soak = st.checkbox("Soak before the hold", value=False, key="allan.soak")
    if grade is None or not st.button("Run on the simulated rig", type="primary", key="allan.run"):
        return None
    with st.spinner("recording and analysing..."):
        seq = PROC.sequence(forms.load_spec(grade), duration_s=float(minutes) * 60.0,
                            temperature_c=float(temperature), soak=soak)
        session, _ = simulate(seq, grade, seed=seed)
        hold = max(session.steps_of_kind("static"), key=lambda step: step.duration)
        st.session_state["allan.samples"] = (session.step_samples(hold.index)[["gx", "gy", "gz"]],
                                             float(session.sample_rate_hz))
        return PROC.analyze(session)


def _statistic() -> None:
    """Any statistic of the family (workbench.analysis.stability) on the simulated hold's gyro."""
    from workbench.analysis.stability import STATS, stability, to_phase
    from workbench.analysis.stability_ci import intervals

    samples = st.session_state.get("allan.samples")
    if samples is None:
        return
    st.subheader("Stability statistics (gyro, rad/s; 95 % intervals)")
    stat = st.selectbox("Statistic", STATS, index=STATS.index("oadev"), key="allan.stat")
    frame, rate = samples
    rows = []
    for col in frame.columns:
        y = frame[col].to_numpy(float)
        ci = intervals(stability(y, rate, stat, "freq", "octave"), to_phase(y, rate, "freq"))
        rows += [{"column": col, "tau s": ci.curve.tau[k], stat: ci.curve.dev[k], "lo": ci.lo[k], "hi": ci.hi[k],
                  "alpha": ci.alpha[k], "edf": ci.edf[k]} for k in range(len(ci.curve.tau))]
    st.dataframe(pd.DataFrame(rows), hide_index=True, use_container_width=True)


def main() -> None:
    st.title(TITLE)
    st.caption("Overlapping Allan deviation with 95 % chi-squared intervals (Greenhall EDF), IEEE Std 952 "
               "noise terms with model selection; 'not observed' terms show the upper bound the record allows.")
    recorded = bool(results.session_dirs(PROC.NAME))  # a store with allan sessions opens on them
    source = st.radio("Data", ["Simulated rig", "Recorded session"], index=1 if recorded else 0, horizontal=True,
                      key="allan.source")
    result = None
    with ui.guarded("allan", catch_all=True):
        result = _simulated() if source == "Simulated rig" else results.result_picker(PROC.NAME, key="allan.pick")
    if result is not None:
        st.session_state["allan.result"] = result
    result = st.session_state.get("allan.result")
    if result is None:
        return
    for w in result.warnings:
        st.warning(w)
    st.pyplot(PROC.figures(result)["adev"])
    st.subheader("Noise terms (lab units, 95 % intervals)")
    st.dataframe(pd.DataFrame(PROC.noise_terms_lab(result)), hide_index=True, use_container_width=True)
    st.text("\n".join(result.summary))
    with ui.guarded("allan.stat", catch_all=True):
        _statistic()


main()
