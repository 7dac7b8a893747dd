"""Session format: time gaps between steps are normal, inside a step an error; the rate is checked.

Every procedure must analyse a session whose recorder paused between steps (no samples while
the table moved) exactly like the same session with the between-step samples kept: the
analyses read only the samples labelled with a step.
"""

import json
import re
import shutil
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from tests.core.test_session import _copy
from tests.nav.conftest import calibration_from_truth
from workbench.errors import SessionError
from workbench.grades import draw_unit, load_spec
from workbench.registry import procedure
from workbench.sequence import Hold, Sequence
from workbench.session import load_session
from workbench.jobs import simulate


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    d = tmp_path_factory.mktemp("gaps") / "session"
    simulate(Sequence("two", [Hold("z-down", dwell_s=5.0), Hold("x-up", dwell_s=5.0)]), "industrial_mems", 1, d)
    return d


def test_no_samples_between_steps_is_a_valid_session(recorded, tmp_path):
    full = load_session(recorded)
    gapped = load_session(_copy(recorded, tmp_path, edit_samples=lambda df: df[df.step >= 0]))
    t = gapped.samples["t"].to_numpy()
    assert np.diff(t).max() > 1.0  # the table moved unrecorded between the two holds
    for i in (0, 1):
        assert np.array_equal(gapped.gyro(i), full.gyro(i))


def test_gap_inside_a_step_names_the_step(recorded, tmp_path):
    def cut(df):
        inside = np.flatnonzero(df.step.to_numpy() == 1)
        return df.drop(index=df.index[inside[100:160]])
    d = _copy(recorded, tmp_path, edit_samples=cut)
    with pytest.raises(SessionError, match=r"step 1: column t: gap of 0\.61 s .* inside the step"):
        load_session(d)
    with pytest.raises(SessionError, match=r"step 1: column t: gap"):
        load_session(d, lazy=True)
    assert len(load_session(d, gaps_in_steps=True).gyro(1)) == 440  # a gap-aware analysis may read it


def test_sample_rate_disagreeing_with_the_time_column_names_both(recorded, tmp_path):
    d = _copy(recorded, tmp_path, edit_manifest=lambda m: m.__setitem__("sample_rate_hz", 200.0))
    with pytest.raises(SessionError, match=r"sample_rate_hz 200 Hz disagrees with column t.* gives 100 Hz"):
        load_session(d)
    # within 1 %: accepted (a crystal's tolerance)
    load_session(_copy(recorded, tmp_path / "b", edit_manifest=lambda m: m.__setitem__("sample_rate_hz", 100.5)))


# Procedures shortened so that each records and analyses in about a second; the unit grades
# are those the procedures are written for (a magnetometer unit, a CVG for north-finding).
# allan records one hold (no pause between steps possible); its gaps inside the record are the
# Allan gap policy's business.
SHORT = {
    "ahrs-table": ("consumer_9axis", {"rotate_s": 20.0, "dwell_s": 5.0}),
    "carousel": ("cvg_two_axis", {"laps": 2}),
    "earth-rate": ("cvg_two_axis", {"turns": 1, "step_deg": 45.0, "dwell_s": 5.0}),
    "ferraris": ("industrial_mems", {}),
    "magnetometer": ("consumer_9axis", {"dwell_s": 2.0, "yaw_steps": 6}),
    "maytagging": ("cvg_two_axis", {"count": 4, "dwell_s": 10.0}),
    "multiposition": ("industrial_mems", {"dwell_s": 5.0}),
    "rate": ("industrial_mems", {"min_duration_s": 2.0}),
    "redundant": ("cvg_two_axis", {"turns": 2, "dwell_s": 10.0}),
    "thermal": ("industrial_mems", {"t_min_c": 10.0, "t_max_c": 40.0, "step_c": 30.0, "dwell_s": 10.0}),
    "zupt-alignment": ("industrial_mems", {"dwell_s": 30.0}),
}


# Diagnostics read from the windows just before/after a step (NaN, so left out, without samples there).
OUTSIDE_STEPS = {"ferraris": r"^\.turns\[\d\]\.(axis_tilt|gravity_change|(motion|rate_rms)_(before|after))$"}
# Procedures whose filters need the motion between steps recorded.
CONTINUOUS = {"ahrs-table"}


def _numbers(doc, prefix=""):
    """Flatten a result dict into {path: float array} of its numeric leaves."""
    out = {}
    if isinstance(doc, dict):
        for k, v in doc.items():
            out.update(_numbers(v, f"{prefix}.{k}"))
    elif isinstance(doc, (list, tuple)):
        try:
            arr = np.asarray(doc, float)
            out[prefix] = arr
        except (TypeError, ValueError):
            for i, v in enumerate(doc):
                out.update(_numbers(v, f"{prefix}[{i}]"))
    elif isinstance(doc, (int, float)) and not isinstance(doc, bool):
        out[prefix] = np.asarray(float(doc))
    return out


@pytest.mark.parametrize("name", sorted(SHORT))
def test_every_procedure_analyses_a_gapped_session_like_the_full_one(name, tmp_path):
    unit, opts = SHORT[name]
    proc, spec = procedure(name), load_spec(unit)
    truth = draw_unit(spec, 3)
    if name == "thermal":  # the chamber's soaks last an hour: 10 Hz keeps the record small
        truth = replace(truth, sample_rate_hz=10.0)
    simulate(proc.sequence(spec, **{**proc.DEFAULTS, **opts}), truth, 3, tmp_path / "full", procedure=name)
    full = load_session(tmp_path / "full")
    gapped_dir = tmp_path / "gapped"
    shutil.copytree(tmp_path / "full", gapped_dir)
    df = pd.read_parquet(gapped_dir / "samples.parquet")
    df[df.step >= 0].reset_index(drop=True).to_parquet(gapped_dir / "samples.parquet")
    gapped = load_session(gapped_dir)
    dt = np.diff(gapped.samples["t"].to_numpy())
    if len(gapped.steps) > 1:
        assert dt.max() > 2.5 / gapped.sample_rate_hz, "the shortened sequence has no pause between steps"
    extra = {"calibration": calibration_from_truth(truth)} if name in ("ahrs-table", "zupt-alignment") else {}
    if name in CONTINUOUS:
        # the attitude filters propagate through the table's motion between steps: a pause
        # there is refused with the time of the gap, not filtered across
        with pytest.raises(SessionError, match=r"column t: gap of .* the filters need gap-free samples"):
            proc.analyze(gapped, **extra)
        return
    a, b = (_numbers(proc.analyze(s, **extra).result) for s in (full, gapped))
    # only diagnostics of the motion between steps are missing without the samples there
    missing = {k for k in a.keys() - b.keys() if not OUTSIDE_STEPS.get(name) or not re.search(OUTSIDE_STEPS[name], k)}
    assert not missing and not b.keys() - a.keys(), missing
    a = {k: v for k, v in a.items() if k in b}
    # The same samples in every step: the numbers agree to rounding.
    for key in a:
        assert a[key].shape == b[key].shape, key
        assert np.allclose(a[key], b[key], rtol=1e-9, atol=1e-12, equal_nan=True), key
