import json

import pytest

from tests.core.test_store import a_set
from workbench.cli import main
from workbench.store import Store


@pytest.fixture
def db(tmp_path, monkeypatch):
    url = f"sqlite:///{tmp_path}/w.db"
    monkeypatch.setenv("WORKBENCH_DB", url)
    return url


def test_sets_list_show_diff_export(db, tmp_path, capsys):
    s1, s2 = a_set(bias=0.01), a_set(bias=0.02)
    Store(db).add_set(s1)
    path = s2.save(tmp_path / "s2.json")
    assert main(["sets", "list"]) == 0
    assert main(["sets", "list", "--format", "json"]) == 0
    listing = capsys.readouterr().out
    assert s1.id[:8] in listing and '"serial": "U1"' in listing
    assert main(["sets", "show", s1.id[:8]]) == 0
    shown = capsys.readouterr().out
    assert "bias" in shown and "mg" in shown
    assert main(["sets", "diff", s1.id, str(path)]) == 0
    assert "1 coefficient(s) differ" in capsys.readouterr().out
    out_file = tmp_path / "e.yaml"
    assert main(["sets", "export", str(path), "--format", "yaml", "--out", str(out_file)]) == 0
    assert "workbench-calibration/1" in out_file.read_text()
    capsys.readouterr()
    assert main(["sets", "export", s1.id, "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["id"] == s1.id


def test_sets_list_on_an_empty_store_says_so(db, capsys):
    # issue 23: an empty store prints one clear line naming the store, exit 0 (not nothing)
    assert main(["sets", "list"]) == 0
    assert " ".join(capsys.readouterr().out.split()) == f"no calibration sets in {db}"  # may wrap before the path
    Store(db).add_set(a_set(serial="U1"))
    assert main(["sets", "list", "--unit", "U2"]) == 0
    assert " ".join(capsys.readouterr().out.split()) == f"no calibration sets of unit U2 in {db}"
    assert main(["sets", "list", "--format", "json", "--unit", "U2"]) == 0
    assert json.loads(capsys.readouterr().out) == []  # machine-readable output stays plain JSON


@pytest.mark.parametrize("args,match", [
    (["sets", "export", "X", "--format", "nope"], "unknown export format 'nope'"),
    (["sets", "show", "deadbeef"], "not in the store"),
])
def test_errors_are_one_line_with_nonzero_exit(db, capsys, args, match):
    if "nope" in args:
        args[2] = str(a_set().save(Store(db).engine.url.database + ".json"))
    assert main(args) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") <= 2


def test_bad_file_leaves_store_unchanged(db, tmp_path, capsys):
    bad = tmp_path / "bad.json"
    d = a_set().to_dict()
    d["accel"]["bias"] = [1, float("nan"), 2]
    bad.write_text(json.dumps(d).replace("NaN", "NaN"))
    assert main(["sets", "merge", str(bad)]) == 2
    assert "bad.json" in capsys.readouterr().err
    assert Store(db).list_sets() == []
    assert main(["--db", f"sqlite:///{tmp_path}/no/such/dir.db", "sets", "list"]) == 2


def test_sets_export_yaml_reads_back_with_sets_show(db, tmp_path, capsys):
    """`sets export --format yaml` is a file `sets show` (and CalibrationSet.load) reads back unchanged."""
    from workbench.calset import CalibrationSet

    s1 = a_set(bias=0.01)
    Store(db).add_set(s1)
    out_file = tmp_path / "s1.yaml"
    assert main(["sets", "export", s1.id, "--format", "yaml", "--out", str(out_file)]) == 0
    assert CalibrationSet.load(out_file).sha256() == s1.sha256()
    capsys.readouterr()
    assert main(["sets", "show", str(out_file)]) == 0
    assert s1.id in capsys.readouterr().out


def test_sets_yaml_with_an_alias_is_refused(db, tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("a: &x [1, 2]\nb: *x\n")
    assert main(["sets", "show", str(bad)]) == 2
    assert "aliases" in capsys.readouterr().err


def test_sets_show_and_diff_fit_80_columns(db, tmp_path, capsys, monkeypatch):
    """At 80 columns every line fits, in lab units, and the diff says 'not observed' instead of a change in sigma."""
    import numpy as np

    from workbench.calset import CalibrationSet, TriadCalibration, Unit
    from workbench.cli import out
    from workbench.model import ThermalModel, TriadModel

    monkeypatch.setattr(out, "_width", 80)
    th = ThermalModel(23.0, np.array([[0.0, 1e-5, 1e-7]] * 3), np.array([[0.0, 1e-5]] * 3))
    gyro = TriadCalibration(TriadModel(bias=[1e-4, 2e-4, 0.0], scale_misalignment=np.full((3, 3), 1e-4),
                                       nonlinearity=[1e-6, 0, 0], g_sensitivity=np.full((3, 3), 1e-5), thermal=th),
                            {"bias": np.array([1e-6, 1e-6, np.nan]), "nonlinearity": np.full(3, 1e-7)})
    name = "a-long-serial-number-of-a-unit.with-a.path-like-part-0123456789X"  # 64: the longest serial
    a = CalibrationSet(Unit(name, "industrial_mems"), {"gyro": gyro},
                       noise={"gyro": {"arw": [1e-4, None, 1e-4], "arw_ci95": [[9e-5, 1.1e-4], None, [9e-5, 1.1e-4]]}})
    b_gyro = TriadCalibration(TriadModel(bias=[1.1e-4, 0.0, 3e-4]), {"bias": np.array([1e-6, np.nan, 1e-6])})
    b = CalibrationSet(Unit(name, "industrial_mems"), {"gyro": b_gyro})
    Store(db).add_set(a)
    pb = b.save(tmp_path / "b.json")
    capsys.readouterr()
    assert main(["sets", "show", a.id]) == 0
    shown = capsys.readouterr().out
    assert max(len(line) for line in shown.splitlines()) <= 80
    for text in ("°/h", "mrad", "ppm/(°/s)", "°/h/g", "°/h/°C²", "°/√h", "misalignment M[x,y]", "not observed"):
        assert text in shown, text
    assert "deg/h" not in shown and "1/SI" not in shown
    assert main(["sets", "list"]) == 0
    assert name in capsys.readouterr().out  # not truncated: the list is key: value lines
    assert main(["sets", "diff", a.id, str(pb)]) == 0
    diff = capsys.readouterr().out
    assert max(len(line) for line in diff.splitlines()) <= 80
    assert "not observed in B" in diff and "not observed in A" in diff and "+7.07" in diff  # 1e-5 / sqrt(2) / 1e-6


def _store_before_the_serial_rule(db: str, serial: str = "SN 0042/a") -> str:
    """A store holding a set whose serial breaks today's rule (written before it): the row edited in SQL."""
    import sqlite3

    s = a_set(bias=0.01)
    Store(db).add_set(s)
    con = sqlite3.connect(db.removeprefix("sqlite:///"))
    body = json.loads(con.execute("select body from calibration_sets").fetchone()[0])
    body["unit"]["serial"] = serial
    con.execute("update calibration_sets set body = ?, serial = ?", (json.dumps(body), serial))
    con.execute("update units set serial = ?", (serial,))
    con.commit()
    con.close()
    return s.id


def test_a_store_from_before_the_serial_rule_stays_readable(db, tmp_path, capsys):
    set_id = _store_before_the_serial_rule(db)
    for args in (["sets", "list"], ["sets", "show", set_id[:8]], ["sets", "diff", set_id, set_id]):
        assert main(args) == 0, args  # were all 'unit.serial ...: use 1-64 letters' refusals (show, diff)
        captured = capsys.readouterr()
        assert "SN 0042/a" in captured.out or args[1] == "diff"
        (warning,) = set(captured.err.strip().splitlines())  # diff reads it twice (A and B)
        assert warning.startswith(f"warning: store set {set_id}: unit.serial 'SN 0042/a'") and "readable" in warning
    assert Store(db).get_set(set_id).unit.serial == "SN 0042/a"


@pytest.mark.parametrize("args", [
    ["sets", "export", "ID", "--format", "c-header"],  # the serial goes verbatim into a C comment and guard
    ["sets", "export", "ID", "--format", "json"],
    ["sets", "merge", "ID"],  # storing a new set with that serial
    ["sets", "merge", "ID", "--no-store", "--out", "OUT"],
])
def test_exporting_or_storing_a_set_with_such_a_serial_is_one_line(db, tmp_path, capsys, args):
    set_id = _store_before_the_serial_rule(db)
    out_file = tmp_path / "merged.json"
    args = [set_id if a == "ID" else str(out_file) if a == "OUT" else a for a in args]
    assert main(args) == 2
    captured = capsys.readouterr()
    (line,) = captured.err.strip().splitlines()
    assert line.startswith("error: set ") and "unit.serial 'SN 0042/a': use 1-64 letters" in line, line
    assert captured.out == "" and not out_file.exists() and len(Store(db).list_sets()) == 1


def test_sets_diff_of_two_models_is_one_line(db, tmp_path, capsys):
    from workbench.calset import CalibrationSet, Unit

    a = a_set(bias=0.01)
    b = CalibrationSet(Unit("U9", "other-grade"), a.triads)
    pa, pb = a.save(tmp_path / "a.json"), b.save(tmp_path / "b.json")
    assert main(["sets", "diff", str(pa), str(pb)]) == 2  # was a silent table of 0 differences
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "is a 'm' (U1), B" in line and "a 'other-grade' (U9): different models" in line


@pytest.mark.parametrize("by,comment,match", [
    ("", "", "the approver's name is blank"),  # was stored: listed as 'approved by —', yet 'already approved'
    ("  ", "", "the approver's name is blank"),
    ("eve\nfake line", "", "approver 'eve\\\\nfake line': expected one line"),
    ("eve", "\x1b[2J", "approval comment '\\\\x1b\\[2J': expected one line"),
])
def test_an_approval_without_a_name_or_with_control_characters_is_refused(db, capsys, by, comment, match):
    import re

    s = a_set()
    Store(db).add_set(s)
    assert main(["sets", "approve", s.id, "--by", by, "--comment", comment]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert re.search(match, line), line
    assert Store(db).approval(s.id) is None
    assert main(["sets", "approve", s.id, "--by", "eve"]) == 0 and Store(db).approval(s.id)["approved_by"] == "eve"


def test_sets_stats_of_a_model_not_in_the_store_is_one_line(db, capsys):
    Store(db).add_set(a_set())
    assert main(["sets", "stats", "--grade", "nosuch"]) == 2  # was an empty table, exit 0
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "--grade 'nosuch': no unit of that model" in line and "(known: m)" in line
    assert main(["sets", "stats", "--grade", "m"]) == 0
