import json
import shutil

import numpy as np
import pandas as pd
import pytest

from workbench.errors import SessionError
from workbench.sequence import Hold, Sequence
from workbench.session import load_session
from workbench.jobs import simulate


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    d = tmp_path_factory.mktemp("s") / "session"
    simulate(Sequence("two", [Hold("z-down", dwell_s=5.0), Hold("x-up", dwell_s=5.0)]), "industrial_mems", 1, d)
    return d


def _copy(recorded, tmp_path, edit_samples=None, edit_manifest=None, csv=False):
    d = tmp_path / "copy"
    shutil.copytree(recorded, d)
    df = pd.read_parquet(d / "samples.parquet")
    if edit_samples:
        df = edit_samples(df)
    (d / "samples.parquet").unlink()
    if csv:
        df.to_csv(d / "samples.csv", index=False)
    else:
        df.to_parquet(d / "samples.parquet")
    if edit_manifest:
        m = json.loads((d / "session.json").read_text())
        edit_manifest(m)
        (d / "session.json").write_text(json.dumps(m))
    return d


def test_round_trip_and_csv_accepted(recorded, tmp_path):
    s = load_session(recorded)
    assert [st.kind for st in s.steps] == ["static", "static"]
    assert (recorded / "truth.json").exists()
    c = load_session(_copy(recorded, tmp_path, csv=True))
    assert np.allclose(c.samples[["gx", "ax"]].to_numpy(), s.samples[["gx", "ax"]].to_numpy())


def _set(df, col, row, value):
    df.loc[row, col] = value
    return df


@pytest.mark.parametrize("edit,match", [
    (lambda df: _set(df, "gx", 100, np.nan), "column gx: NaN .* row 100"),
    (lambda df: df.drop(index=range(200, 260)).reset_index(drop=True), "column t: gap"),
    (lambda df: _set(df, "t", 50, df["t"][49]), "column t: duplicate or non-increasing .* row 50"),
    (lambda df: df.drop(columns=["az"]), "missing column.* az"),
    (lambda df: df.assign(ax=df.ax / 9.80665, ay=df.ay / 9.80665, az=df.az / 9.80665), "not m/s\\^2"),
    (lambda df: df.assign(gx=np.degrees(df.gx) + 100.0), "not rad/s"),
    (lambda df: _set(df, "step", 10, 7), "label.*7.* match no step"),
    # a Parquet file with the wrong column types: text steps were a TypeError traceback in the step index,
    # a boolean gyro was analysed, a fractional step label matched no step silently
    (lambda df: df.assign(step=df.step.astype(str)), "column step: not numeric \\(str values\\)"),
    (lambda df: df.assign(gx=df.gx > 0), "column gx: not numeric \\(bool values\\)"),
    (lambda df: df.assign(t=df.t.astype(str)), "column t: not numeric"),
    (lambda df: _set(df.assign(step=df.step.astype(float)), "step", 10, 0.5), "column step: 0.5 at row 10 is not a whole"),
])
def test_bad_samples_get_errors_naming_the_column(recorded, tmp_path, edit, match):
    with pytest.raises(SessionError, match=match) as exc:
        load_session(_copy(recorded, tmp_path, edit_samples=edit))
    assert "samples.parquet" in str(exc.value)


@pytest.mark.parametrize("edit,match", [
    (lambda m: m["steps"][1].__setitem__("t_start", m["steps"][0]["t_end"] - 1.0), "step 1 overlaps step 0"),
    (lambda m: m["steps"][1].__setitem__("t_end", m["steps"][1]["t_end"] + 100.0), "step 1.*outside"),
    (lambda m: m["site"].pop("latitude_deg"), "latitude_deg"),
    (lambda m: m["steps"][0].__setitem__("kind", "wobble"), "step 0: unknown kind 'wobble'"),
    (lambda m: m.__setitem__("format", "other/1"), "format"),
    # a value of the wrong type names its field (these were ValueError / TypeError tracebacks)
    (lambda m: m["steps"][0].__setitem__("mount", "up"), "step 0: 'mount' must be a finite 3x3 matrix"),
    (lambda m: m["steps"][0].__setitem__("t_start", "soon"), "step 0: t_start: expected a finite number, got 'soon'"),
    (lambda m: m["steps"][1].__setitem__("temperature_c", "warm"), "step 1: temperature_c: expected a finite number"),
    (lambda m: m["site"].__setitem__("latitude_deg", "north"), "site.latitude_deg: expected a finite number"),
    (lambda m: m["site"].__setitem__("height_m", [1]), "site.height_m: expected a finite number"),
    (lambda m: m.__setitem__("steps", 5), "steps: expected a list of step objects"),
    (lambda m: m.__setitem__("unit", "x"), "unit: expected an object with serial and model"),
    (lambda m: m.__setitem__("sample_rate_hz", float("inf")), "sample_rate_hz must be a positive number"),
    # the serial names folders and is written into exports; the model into their comment lines
    (lambda m: m["unit"].__setitem__("serial", "../../etc"), "unit.serial '../../etc': use 1-64 letters, digits"),
    (lambda m: m["unit"].__setitem__("serial", "[bold]x[/]"), "unit.serial"),
    (lambda m: m["unit"].__setitem__("model", "m\nPARAM 1"), "unit.model .*: expected one line of at most 200 printable characters"),
])
def test_bad_manifests(recorded, tmp_path, edit, match):
    with pytest.raises(SessionError, match=match):
        load_session(_copy(recorded, tmp_path, edit_manifest=edit))


@pytest.mark.parametrize("text,match", [
    (b"[1, 2]", "expected a JSON object, got list"),
    (b"\x80\x81{", "not valid JSON"),
])
def test_a_manifest_that_is_not_an_object_or_not_text(recorded, tmp_path, text, match):
    d = _copy(recorded, tmp_path)
    (d / "session.json").write_bytes(text)
    with pytest.raises(SessionError, match=f"session.json: {match}"):
        load_session(d)


@pytest.mark.parametrize("log,match", [
    (b'[1, 2]\n{"step": {"index": 1}}\n', "line 1: expected"),
    (b'{"step": [0]}\n{"step": {"index": 1}}\n', "line 1: expected"),
    (b'\xff\xfe\n{"step": {"index": 1}}\n', "line 1 is not valid JSON"),
])
def test_a_corrupt_step_log_names_its_line(recorded, tmp_path, log, match):
    """An unfinished recording's step log edited or damaged (not only cut short by a kill)."""
    d = _copy(recorded, tmp_path, edit_manifest=lambda m: m.update(complete=False, steps=m["steps"][:1]))
    (d / "steps.jsonl").write_bytes(log)
    with pytest.raises(SessionError, match=f"steps.jsonl: {match}"):
        load_session(d)


def test_lazy_loading_streams_the_same_samples_in_bounded_batches(recorded, tmp_path):
    eager, lazy = load_session(recorded), load_session(recorded, lazy=True)
    assert lazy.samples is None
    for step in (0, 1):
        blocks = list(lazy.stream(["gx", "ay"], step=step, batch_rows=97))
        assert max(len(b) for b in blocks) <= 97
        assert np.array_equal(np.vstack(blocks), eager.step_samples(step)[["gx", "ay"]].to_numpy())
    with pytest.raises(SessionError, match="loaded lazily"):
        lazy.gyro(0)
    bad = _copy(recorded, tmp_path, edit_samples=lambda df: _set(df, "az", 700, np.inf))
    with pytest.raises(SessionError, match="column az: NaN or infinite"):
        load_session(bad, lazy=True)
