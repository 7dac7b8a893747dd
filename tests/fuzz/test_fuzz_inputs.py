"""Property-based fuzzing of every input a user hands the workbench (issue 16).

Session manifests, samples, import profiles, calibration files, rig configurations and
command-line options, each mutated by hypothesis and handed to the CLI entry function
in-process. The property (``assert_refused_cleanly``): the command succeeds, or it prints
one line on stderr and exits 2 with no traceback, leaving the store and the session folders
unchanged. Inputs that are certainly bad (a non-finite limit, NaN samples) must be refused.
Bounded (5-20 examples a property, derandomised, no shrinking) to keep the suite well under two minutes.
"""

from __future__ import annotations

import json

import pandas as pd
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.fuzz.conftest import assert_refused_cleanly, dump
from tests.fuzz.strategies import HOSTILE_TEXT, NON_FINITE, SCALAR, TEXT, VALUE, edited, edits
from workbench.registry import procedures

MANIFEST_KEYS = ["format", "id", "unit", "site", "sample_rate_hz", "procedure", "steps", "complete", "planned"]


@settings(max_examples=6)
@given(data=st.data())
def test_session_manifests(world, data):
    s = world.session_copy()
    manifest = json.loads((s / "session.json").read_text())
    small = {k: manifest[k] for k in manifest if k not in ("planned", "sequence")}  # edits where they matter
    small["steps"] = small["steps"][:2]
    new = data.draw(edits(small))
    full = {**manifest, **new, "steps": new.get("steps", []) + manifest["steps"][2:]} if "steps" in new \
        else {k: v for k, v in {**manifest, **new}.items() if k in new or k in ("planned", "sequence")}
    (s / "session.json").write_text(json.dumps(full))
    assert_refused_cleanly(world, ["analyze", "multiposition", s], [s])


@settings(max_examples=6)
@given(column=st.sampled_from(["t", "step", "gx", "gy", "gz", "ax", "ay", "az"]),
       row=st.integers(0, 10_000), bad=st.one_of(NON_FINITE, st.just("abc")))
def test_samples_with_a_bad_cell_are_refused(world, column, row, bad):
    s = world.session_copy()
    df = pd.read_parquet(s / "samples.parquet")
    df[column] = df[column].astype(object)
    df.loc[row % len(df), column] = bad
    if bad == "abc":
        df[column] = df[column].astype(str)
    df.to_parquet(s / "samples.parquet")
    assert_refused_cleanly(world, ["analyze", "multiposition", s], [s], strict=True)


@settings(max_examples=5)
@given(cut=st.floats(0.0, 0.99), drop=st.sampled_from([None, "t", "gx", "az", "step"]))
def test_truncated_or_incomplete_samples_are_refused(world, cut, drop):
    s = world.session_copy()
    f = s / "samples.parquet"
    if drop is None:
        f.write_bytes(f.read_bytes()[: int(cut * f.stat().st_size)])
    else:
        pd.read_parquet(f).drop(columns=[drop]).to_parquet(f)
    assert_refused_cleanly(world, ["analyze", "multiposition", s], [s], strict=True)


@settings(max_examples=12)
@given(data=st.data())
def test_import_profiles(world, data):
    import yaml

    profile = yaml.safe_load(world.profile.read_text())
    d = world.fresh("profile")
    f = dump(d / "p.yaml", data.draw(edits(profile)))
    out = d / "out"
    code = assert_refused_cleanly(world, ["import", f, world.recording, "--out", out], [world.recording.parent])
    assert code == 0 or not out.exists()  # a refused import leaves no folder


@settings(max_examples=10)
@given(text=st.one_of(TEXT, st.binary(max_size=200).map(lambda b: b.decode("latin-1"))))
def test_import_profiles_as_raw_text(world, text):
    d = world.fresh("raw")
    (d / "p.yaml").write_text(text, encoding="utf-8", errors="surrogatepass")
    assert_refused_cleanly(world, ["import", d / "p.yaml", world.recording, "--out", d / "out"], strict=True)
    assert not (d / "out").exists()


@settings(max_examples=12)
@given(data=st.data())
def test_calibration_files(world, data):
    doc = json.loads(world.set_file.read_text())
    d = world.fresh("set")
    f = dump(d / "set.json", data.draw(edits(doc)), "json")
    assert_refused_cleanly(world, ["sets", "merge", f])


@settings(max_examples=12)
@given(data=st.data())
def test_rig_configurations(world, data):
    d = world.fresh("rig")
    f = dump(d / "rig.yaml", data.draw(edits(world.rig)))
    assert_refused_cleanly(world, ["run", "multiposition", "--rig", f, "--dry-run"])


LIMITS = [("turntable", k) for k in ("max_rate_dps", "max_accel_dps2", "encoder_resolution_deg")] + \
         [("chamber", "max_ramp_c_per_min")]


@settings(max_examples=10)
@given(where=st.sampled_from(LIMITS), value=st.one_of(NON_FINITE, st.floats(max_value=0.0), HOSTILE_TEXT))
def test_a_bad_limit_is_always_refused(world, where, value):
    d = world.fresh("limit")
    f = dump(d / "rig.yaml", edited(world.rig, where, "replace", value))
    assert_refused_cleanly(world, ["run", "multiposition", "--rig", f, "--dry-run"], strict=True)


def _option_argv(draw) -> list[str]:
    names = sorted(procedures())
    proc = draw(st.sampled_from([*names, "campaign"]))
    opts = []
    for _ in range(draw(st.integers(0, 3))):
        key = draw(st.one_of(st.sampled_from(["dwell_s", "positions", "settle_s", "duration_s", "soak"]), TEXT))
        value = draw(st.one_of(SCALAR.map(json.dumps), HOSTILE_TEXT))
        opts += ["-o", f"{key}={value}"]
    return ["run", proc, "--dry-run", *opts]


@st.composite
def argvs(draw) -> list[str]:
    """Command lines: known commands with hostile arguments and options, or nonsense."""
    kind = draw(st.sampled_from(["run", "sets", "allan", "procedures", "rig", "analyze", "noise"]))
    if kind == "run":
        return _option_argv(draw)
    if kind == "sets":
        sub = draw(st.sampled_from(["list", "show", "diff", "export", "merge", "approve", "nope"]))
        return ["sets", sub, *draw(st.lists(st.one_of(HOSTILE_TEXT, st.sampled_from(["--format", "--unit", "--by"])),
                                            max_size=3))]
    if kind == "allan":
        return ["allan", draw(HOSTILE_TEXT), *draw(st.sampled_from([[], ["--rate", "x"], ["--columns", "q"]]))]
    if kind == "procedures":
        return ["procedures", draw(HOSTILE_TEXT)]
    if kind == "rig":
        return ["rig", draw(st.sampled_from(["check", "hil", "nope"])), draw(HOSTILE_TEXT) + ".yaml"]
    if kind == "analyze":
        return ["analyze", draw(st.sampled_from(sorted(procedures()))), draw(HOSTILE_TEXT), "--no-store",
                "-o", f"{draw(TEXT)}={json.dumps(draw(VALUE))}"]
    return draw(st.lists(HOSTILE_TEXT, min_size=1, max_size=4))


@settings(max_examples=20)
@given(argv=argvs())
def test_command_line_options(world, argv):
    assert_refused_cleanly(world, argv, [world.session])




# a cell of a record handed to `workbench allan`: ordinary noise, degenerate and hostile values
CELL = st.one_of(st.floats(-1e-2, 1e-2), NON_FINITE, st.sampled_from([1e308, -1e308, 1e150, 0.0, "", "abc", "1,5"]))


@settings(max_examples=12)
@given(rows=st.integers(0, 400), time=st.sampled_from(["none", "regular", "duplicated", "backwards"]),
       columns=st.integers(0, 3), delimiter=st.sampled_from([",", ";"]), cell=CELL, at=st.integers(0, 10**6),
       rate=st.sampled_from([None, "100", "0", "-1", "nan", "inf", "1e-300"]),
       stat=st.sampled_from([[], ["--stat", "oadev"], ["--stat", "mtie", "--data-type", "phase"]]))
def test_allan_records(world, rows, time, columns, delimiter, cell, at, rate, stat):
    """The record loader of `workbench allan`: any CSV it may meet gives a result or one line, exit 2."""
    import numpy as np

    rng = np.random.default_rng(rows)
    t = np.arange(rows) / 100.0
    if time == "duplicated" and rows > 2:
        t[rows // 2] = t[rows // 2 - 1]
    if time == "backwards" and rows > 2:
        t[rows // 2:] -= 1.0
    names = (["t"] if time != "none" else []) + [f"g{c}" for c in "xyz"[:columns]]
    cells = [[f"{v:.6g}" for v in ([t[i]] if time != "none" else []) + list(rng.normal(0, 1e-3, columns))]
             for i in range(rows)]
    if rows and columns:
        cells[at % rows][-1] = str(cell)
    d = world.fresh("allan")
    f = d / "rec.csv"
    f.write_text(delimiter.join(names) + "\n" + "".join(delimiter.join(r) + "\n" for r in cells))
    assert_refused_cleanly(world, ["allan", f, *(["--rate", rate] if rate else []), *stat], [d])
