"""A session folder's files (workbench.session_files): manifest, step log, samples file, atomic writes."""

import json

import pandas as pd
import pytest

from workbench.errors import SessionError
from workbench.session_files import (parse_manifest, read_manifest, read_samples, recorded_steps, samples_file,
                                     step_log, write_manifest)
from workbench.session_types import FORMAT, STEP_LOG

STEP = {"index": 0, "kind": "static", "t_start": 0.0, "t_end": 1.0}
MANIFEST = {"format": FORMAT, "unit": {"serial": "u1"}, "site": {"latitude_deg": 45.0}, "sample_rate_hz": 100.0,
            "steps": [STEP]}


def test_manifest_round_trip_and_errors(tmp_path):
    write_manifest(tmp_path, MANIFEST)
    assert read_manifest(tmp_path) == MANIFEST and not list(tmp_path.glob("*.tmp*"))
    fields, steps = parse_manifest(MANIFEST, "session.json")
    assert fields["sample_rate_hz"] == 100.0 and [s.index for s in steps] == [0]
    (tmp_path / "session.json").write_text("{")
    with pytest.raises(SessionError, match="session.json: not valid JSON"):
        read_manifest(tmp_path)
    with pytest.raises(SessionError, match="no session.json"):
        read_manifest(_empty(tmp_path))


def _empty(tmp_path):
    d = tmp_path / "empty"
    d.mkdir()
    return d


@pytest.mark.parametrize("edit,match", [
    (lambda m: m.pop("site"), "missing field 'site'"),
    (lambda m: m["site"].update(latitude_deg=91.0), "latitude_deg 91.0 is outside"),
    (lambda m: m.update(sample_rate_hz=0), "sample_rate_hz must be a positive"),
    (lambda m: m.update(steps=[STEP, STEP]), "duplicate step index"),
    (lambda m: m.update(steps=[STEP, {**STEP, "index": 1, "t_start": 0.5, "t_end": 2.0}]), "step 1 overlaps step 0"),
])
def test_parse_manifest_names_the_field(edit, match):
    m = json.loads(json.dumps(MANIFEST))
    edit(m)
    with pytest.raises(SessionError, match=match):
        parse_manifest(m, "session.json")


def test_step_log_of_a_killed_recording(tmp_path):
    entry = {"step": {**STEP, "index": 1, "t_start": 1.0, "t_end": 2.0}, "rig_state": {}}
    again = {"step": {**entry["step"], "t_end": 2.5}, "rig_state": {}}
    (tmp_path / STEP_LOG).write_text(json.dumps(entry) + "\n" + json.dumps(again) + "\n" + '{"step": {"ind')
    assert [e["step"]["t_end"] for e in step_log(tmp_path)] == [2.5]  # the re-recorded step wins, cut line ignored
    assert [s["index"] for s in recorded_steps(tmp_path, MANIFEST)] == [0, 1]
    assert recorded_steps(tmp_path, {**MANIFEST, "complete": True}) == [STEP]
    (tmp_path / STEP_LOG).write_text("not json\n" + json.dumps(entry) + "\n")
    with pytest.raises(SessionError, match="line 1 is not valid JSON"):
        step_log(tmp_path)


def test_samples_file_prefers_parquet_and_unreadable_files_are_one_line(tmp_path):
    assert samples_file(tmp_path) is None
    pd.DataFrame({"t": [0.0]}).to_csv(tmp_path / "samples.csv", index=False)
    assert samples_file(tmp_path).name == "samples.csv"
    (tmp_path / "samples.parquet").write_bytes(b"not parquet")
    assert samples_file(tmp_path).name == "samples.parquet"
    with pytest.raises(SessionError, match="samples.parquet: cannot read samples"):
        read_samples(tmp_path / "samples.parquet")
