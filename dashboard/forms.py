"""Forms of the dashboard: unit grades, procedures, their declared options and sequences, a run panel.

- :func:`grade_picker` / :func:`unit_grades` / :func:`load_spec` — the grade fixtures ``fixtures/units/*.yaml``;
- :func:`procedure_picker` and :func:`option_inputs` — a procedure and widgets for its declared options;
- :func:`build_sequence` / :func:`show_sequence` — a procedure's sequence before it runs;
- :func:`run_panel` — grade, options, sequence preview and a Start button (:func:`dashboard.jobs.start_run`).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from pathlib import Path
from types import ModuleType
from typing import Any

import pandas as pd
import streamlit as st

from dashboard import jobs
from dashboard.ui import format_duration, guarded, lab_label
from workbench import registry

UNITS_DIR = jobs.REPO / "fixtures" / "units"
DEFAULT_GRADE, DEFAULT_PROCEDURE = "industrial_mems", "multiposition"  # preselected: the README's unit, a first run


def unit_grades(directory: Path | None = None) -> dict[str, Path]:
    """Grade fixtures by name (file stem), sorted: ``{'hg1700': Path('.../hg1700.yaml'), ...}``."""
    return {p.stem: p for p in sorted((directory or UNITS_DIR).glob("*.yaml"))}


def grade_picker(label: str = "Unit grade", key: str = "grade") -> Path | None:
    """A select box over ``fixtures/units/*.yaml``; returns the chosen fixture path (None if none exist)."""
    grades = unit_grades()
    if not grades:
        st.info(f"No unit grade fixtures in {UNITS_DIR}.")
        return None
    names = list(grades)
    name = st.selectbox(label, names, key=key, index=names.index(DEFAULT_GRADE) if DEFAULT_GRADE in names else 0)
    return grades[name]


@st.cache_resource(show_spinner=False)
def _spec(path: str, mtime: float):
    from workbench.grades import load_spec

    return load_spec(path)


def load_spec(path: Path):
    """The SensorSpec of a grade fixture (cached per file version); raises WorkbenchError."""
    return _spec(str(path), Path(path).stat().st_mtime)


def procedure_picker(label: str = "Procedure", key: str = "procedure") -> ModuleType | None:
    """A select box over ``registry.procedures()`` showing titles; None (with a note) when none exist."""
    procs = registry.procedures()
    if not procs:
        st.info("No procedures are installed yet (procedures/*.py).")
        return None
    names = sorted(procs)
    name = st.selectbox(label, names, key=key, format_func=lambda n: f"{n} — {getattr(procs[n], 'TITLE', n)}",
                        index=names.index(DEFAULT_PROCEDURE) if DEFAULT_PROCEDURE in names else 0)
    return procs[name]


def option_inputs(proc: ModuleType, key: str, stage: str | None = None) -> dict:
    """Widgets built from the procedure's declared options (:mod:`workbench.options`) of ``stage``
    (default all): choices as a select box, numbers, flags, text; lists and unset values as JSON;
    labelled in lab units, the option's help and command-line name in the help."""
    from workbench.options import declarations

    options: dict = {}
    for opt in (o for o in declarations(proc) if o.in_stage(stage)):
        name, default = opt.name, opt.default
        wkey = f"{key}.{proc.NAME}.{name}"
        label, hint = lab_label(name), f"{opt.help} `workbench run {proc.NAME} -o {name}=...`".strip()
        if opt.choices is not None and default in opt.choices:
            options[name] = st.selectbox(label, list(opt.choices), index=list(opt.choices).index(default), key=wkey,
                                         help=hint)
        elif isinstance(default, bool):
            options[name] = st.checkbox(label, value=default, key=wkey, help=hint)
        elif isinstance(default, int):
            options[name] = int(st.number_input(label, value=default, step=1, key=wkey, help=hint))
        elif isinstance(default, float):
            options[name] = float(st.number_input(label, value=default, format="%g", key=wkey, help=hint))
        elif isinstance(default, str):
            options[name] = st.text_input(label, value=default, key=wkey, help=hint)
        else:  # None (unset) or a list / dict: JSON text, empty = unset
            text = st.text_input(label, value="" if default is None else json.dumps(default), key=wkey, help=hint,
                                 placeholder="not set (JSON value)" if default is None else None)
            try:
                options[name] = json.loads(text) if text.strip() else None
            except json.JSONDecodeError:
                options[name] = text if default is None else default  # a plain word, e.g. a set id
                if default is not None:
                    st.error(f"option {name}: {text!r} is not valid JSON; using the default")
    return options


def build_sequence(proc: ModuleType, grade: Path, options: Mapping | None = None):
    """The procedure's Sequence for the grade fixture: ``proc.sequence(spec, **sequence options)``, the
    options validated and kept for the sequence stage (analysis and rig options are checked, left out)."""
    from workbench.options import validate

    return proc.sequence(load_spec(grade), **validate(proc, options, "sequence"))


def sequence_table(seq: Any) -> pd.DataFrame:
    """One row per expanded step (``Sequence.describe()``: kind, mount, angle °, rate °/s, duration s, setpoint °C)."""
    return pd.DataFrame(seq.describe())


def show_sequence(seq: Any) -> None:
    """Steps table and total time of a Sequence, shown before it runs."""
    table = sequence_table(seq)
    c1, c2 = st.columns(2)
    c1.metric("Steps", len(table))
    c2.metric("Total time (rig time)", format_duration(float(seq.duration_s)))
    st.dataframe(table.rename(columns=lab_label), width="stretch", hide_index=True)


def show_drive(proc: ModuleType, options: Mapping | None = None) -> tuple[float, int]:
    """Road legs and total time of a drive procedure (``proc.legs(**sequence options)``), shown before it
    runs; returns (duration s at the legs' target speeds, number of legs)."""
    from workbench.options import validate
    from workbench.sim.roads import leg_duration

    legs = proc.legs(**validate(proc, options, "sequence"))
    duration_s = float(sum(leg_duration(leg) for leg in legs))
    c1, c2 = st.columns(2)
    c1.metric("Road legs", len(legs))
    c2.metric("Total time (drive time)", format_duration(duration_s))
    st.dataframe(pd.DataFrame(legs), width="stretch", hide_index=True)
    return duration_s, len(legs)


def run_panel(name: str, key: str, context: str, check: Callable[[Any], None] | None = None) -> None:
    """Grade, options, sequence preview, seed and a Start button for procedure ``name`` on the simulated rig.

    ``check(spec)`` may show warnings for the chosen grade (e.g. a procedure that does not apply).
    """
    grade = grade_picker(key=f"{key}.grade")
    with guarded(context):
        proc = registry.procedure(name)
        options = option_inputs(proc, key=f"{key}.run")
        if grade is None:
            return
        if check is not None:
            check(load_spec(grade))
        if getattr(proc, "DRIVE", False):  # the simulated vehicle drives road legs, not a turntable sequence
            duration_s, n_steps = show_drive(proc, options)
        else:
            seq = build_sequence(proc, grade, options)
            show_sequence(seq)
            duration_s, n_steps = seq.duration_s, len(seq.expand())
        seed = st.number_input("Seed", value=1, step=1, key=f"{key}.seed")
        if st.button("Start run", key=f"{key}.start"):
            folder = jobs.start_run(name, grade, int(seed), options, duration_s, n_steps)
            st.success(f"started: {folder}")
