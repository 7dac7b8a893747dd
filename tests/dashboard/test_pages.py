"""AppTest checks of the general dashboard pages: widgets, the calibration-set workflow, error paths."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from streamlit.testing.v1 import AppTest

REPO = Path(__file__).resolve().parents[2]
PAGES = REPO / "dashboard" / "pages"
TIMEOUT = 60  # s per script run (first imports of pandas/matplotlib on a loaded 2-core box)


def page(name: str) -> AppTest:
    at = AppTest.from_file(str(PAGES / name), default_timeout=TIMEOUT)
    return at.run()


def texts(at: AppTest, kind: str) -> list[str]:
    return [e.value for e in getattr(at, kind)]


def test_app_discovers_pages_in_prefix_order():
    import importlib.util

    spec = importlib.util.spec_from_file_location("dash_app", REPO / "app.py")
    app = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(app)  # not __main__: defines discover() without running Streamlit
    found = app.discover()
    orders = [o for o, *_ in found]
    assert orders == sorted(orders) and orders[0] == 10
    titles = {name: title for _, name, title, _ in found}
    assert titles["overview"] == "Overview" and titles["calibration_sets"] == "Calibration sets"


def test_app_titles_from_constant_or_file_name(tmp_path):
    import importlib.util

    spec = importlib.util.spec_from_file_location("dash_app", REPO / "app.py")
    app = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(app)
    (tmp_path / "40_north_finding.py").write_text("import streamlit as st\n")
    (tmp_path / "5_first.py").write_text('TITLE = "First page"\n')
    (tmp_path / "helpers.py").write_text("")  # not a page: no NN_ prefix
    assert [(o, n, t) for o, n, t, _ in app.discover(tmp_path)] == [(5, "first", "First page"),
                                                                     (40, "north_finding", "North finding")]


def test_app_runs_and_shows_overview(seeded_db):
    at = AppTest.from_file(str(REPO / "app.py"), default_timeout=TIMEOUT).run()
    assert not at.exception
    assert "Calibration workbench" in texts(at, "title")
    assert [m.value for m in at.metric][:2] == ["1", "2"]  # one unit, two sets


def test_overview_store_caption_is_the_url_as_typed(tmp_path, monkeypatch):
    folder = tmp_path / "lab `a` *b*"
    folder.mkdir()
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{folder}/wb.db")
    at = page("10_overview.py")
    assert not at.exception
    assert f"Store: sqlite:///{tmp_path}/lab \\`a\\` \\*b\\*/wb.db" in texts(at, "caption")


def test_overview_store_error_is_readable(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{tmp_path}/missing/dir/wb.db")
    at = page("10_overview.py")
    assert not at.exception
    assert any("does not exist" in e for e in texts(at, "error"))


def test_calibration_sets_show_diff_and_approve(seeded_db):
    at = page("95_calibration_sets.py")
    assert not at.exception
    assert at.selectbox(key="cal.unit").value == "DASH-001"
    assert at.selectbox(key="cal.version").value == 2  # newest first
    # the z bias sigma is NaN in the set: shown as not observed, never as zero
    coeffs = at.dataframe[1].value
    z_bias = coeffs[(coeffs.field == "bias") & (coeffs["index"] == "[2]")]
    assert z_bias.sigma.iloc[0] == "not observed"
    # diff: only gyro bias x changed, by 3e-6 / sqrt(2 * 1e-6^2) = 2.121 sigma
    diff = at.dataframe[-1].value
    bias_rows = diff[diff.field == "bias"]
    assert len(bias_rows) == 1 and bias_rows["change (σ)"].iloc[0] == pytest.approx(3 / 2 ** 0.5, rel=1e-9)
    # approve needs a name; then the store records it and the page says so
    assert at.button(key="cal.approve").disabled
    at.text_input(key="cal.by").input("lab-lead").run()
    at.button(key="cal.approve").click().run()
    assert not at.exception
    assert seeded_db.list_sets()[0].approved_by == "lab-lead"
    assert any("Approved by lab-lead" in s for s in texts(at, "success"))


def test_calibration_sets_download_every_format(seeded_db):
    from workbench import registry

    at = page("95_calibration_sets.py")
    assert not at.exception
    # every installed format gives a download button, or a readable error naming the format when the
    # set cannot be expressed in it (e.g. a format needing a noise term the set has as not observed)
    labels = [b.proto.label for b in at.get("download_button")]
    refused = texts(at, "warning")
    assert not at.error
    for fmt, mod in registry.exporters().items():
        n = labels.count(f"{fmt} ({mod.SUFFIX})") + sum(w.startswith(f"{fmt} ({mod.SUFFIX}) not available:")
                                                       for w in refused)
        assert n == 1, f"format {fmt}: no download button and no error"
    assert "json (.json)" in labels  # the canonical format always exports


def test_calibration_sets_empty_store(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{tmp_path / 'empty.db'}")
    at = page("95_calibration_sets.py")
    assert not at.exception
    assert any("No units" in i for i in texts(at, "info"))


# -- Run page: a fake procedure and a fake `workbench run` (tests/dashboard/fake_workbench.py) ------------
def _fake_procedure(name: str, broken_sequence: bool = False):
    from types import SimpleNamespace

    from workbench.errors import RigLimitError
    from workbench.sequence import Hold, Sequence

    def sequence(spec, dwell_s=10.0):
        if broken_sequence:
            raise RigLimitError("sequence broken: Rotate rate 20 rad/s exceeds the table limit 10 rad/s")
        return Sequence(name, [Hold("z-down", 0.0, dwell_s), Hold("x-up", 0.0, dwell_s), Hold("y-up", 0.0, dwell_s)])

    return SimpleNamespace(NAME=name, TITLE=f"fake {name}", TRIADS=("gyro",), DEFAULTS={"dwell_s": 10.0},
                           sequence=sequence, analyze=None, figures=lambda r: {})


@pytest.fixture
def fake_run(seeded_db, tmp_path, monkeypatch):
    """Procedures ``ok``, ``fails`` (fails mid-run) and ``broken`` (bad sequence); one grade; the fake CLI."""
    import sys

    from dashboard import forms, jobs
    from workbench import registry

    procs = {"ok": _fake_procedure("ok"), "fails": _fake_procedure("fails"), "slow": _fake_procedure("slow"),
             "broken": _fake_procedure("broken", broken_sequence=True)}
    monkeypatch.setattr(registry, "procedures", lambda: procs)
    grades = tmp_path / "grades"
    grades.mkdir()
    (grades / "test_grade.yaml").write_text("name: test_grade\n")
    monkeypatch.setattr(forms, "UNITS_DIR", grades)
    monkeypatch.setattr(forms, "load_spec", lambda path: None)
    monkeypatch.setattr(jobs, "_workbench_cli", lambda: [sys.executable, str(Path(__file__).with_name(
        "fake_workbench.py"))])
    return procs


def _wait_for_end(folder: Path, timeout_s: float = 30.0) -> None:
    import time

    from dashboard import jobs

    t0 = time.monotonic()
    while (folder / jobs.EXIT_FILE).exists() is False and time.monotonic() - t0 < timeout_s:
        time.sleep(0.1)
    assert (folder / jobs.EXIT_FILE).exists(), f"fake run in {folder} did not end in {timeout_s} s"


def test_run_page_previews_sequence_and_runs(fake_run):
    at = page("20_run.py")
    assert not at.exception
    at.selectbox(key="run.procedure").select("ok").run()
    # preview: 3 steps of 10 s = 30 s of rig time, shown before anything starts
    assert [m.value for m in at.metric][:2] == ["3", "30 s"]
    at.number_input(key="run.options.ok.dwell_s").set_value(20.0).run()
    assert [m.value for m in at.metric][:2] == ["3", "1 min 00 s"]
    at.button(key="run.start").click().run()
    assert not at.exception
    folder = Path(at.session_state["run.folder"])
    _wait_for_end(folder)
    at.run()
    assert not at.exception and not at.error
    assert any("finished: 3 steps recorded" in s for s in texts(at, "success"))
    assert any("fake warning" in w for w in texts(at, "warning"))
    job = __import__("json").loads((folder / "job.json").read_text())
    assert job["options"] == {"dwell_s": 20.0} and "--option" in job["command"]


def test_run_page_run_failing_mid_run_shows_its_error_and_stores_nothing(fake_run, seeded_db):
    at = page("20_run.py")
    at.selectbox(key="run.procedure").select("fails").run()
    at.button(key="run.start").click().run()
    folder = Path(at.session_state["run.folder"])
    _wait_for_end(folder)
    at.run()
    assert not at.exception
    (error,) = [e for e in texts(at, "error") if "failed (exit code 2)" in e]
    assert "after 1 of 3 steps" in error  # from the runner's step log, not from the CLI's output
    assert error.endswith("step 0 (static): gyro norm 0.8 rad/s is not static")  # the CLI's one-line error
    assert len(seeded_db.list_sets()) == 2 and seeded_db.list_sessions() == []


def test_run_page_stop_a_run(fake_run):
    import time

    at = page("20_run.py")
    at.selectbox(key="run.procedure").select("slow").run()
    at.button(key="run.start").click().run()
    folder = Path(at.session_state["run.folder"])
    # while it records: the progress bar counts steps and the partial plots show the recorded parts
    from dashboard import jobs

    t0 = time.monotonic()
    while jobs.run_status(folder).steps_done < 1 and time.monotonic() - t0 < 15:
        time.sleep(0.1)
    at.run()
    (bar,) = at.get("progress")
    # 1 of 3 steps (or 2 on a slow machine: a step takes 3 s) of 10 s each = 33 % (67 %) of the 30 s planned
    assert re.search(r"(1 of 3 steps recorded \(33 %|2 of 3 steps recorded \(67 %) of rig time", bar.proto.text)
    assert any("gyro (body frame)" in c.value for c in at.caption)
    at.button(key="run.stop").click().run()
    t0 = time.monotonic()
    while not any("was stopped" in e for e in texts(at, "error")) and time.monotonic() - t0 < 10:
        time.sleep(0.2)
        at.run()
    assert any("was stopped" in e for e in texts(at, "error"))
    assert not (folder / "exit_code").exists() and not list(folder.rglob("result.json"))


def test_run_page_bad_sequence_is_a_readable_error(fake_run):
    at = page("20_run.py")
    at.selectbox(key="run.procedure").select("broken").run()
    assert not at.exception
    assert any("exceeds the table limit" in e for e in texts(at, "error"))
    assert not [b for b in at.button if b.key == "run.start"]  # nothing to start


def test_run_page_caption_is_the_command_as_typed(fake_run, tmp_path, monkeypatch):
    """The run's command is shown shell-quoted with its user text literal: it was wrapped in backticks, so a
    backtick in an option value (or a job without a command) left a stray backtick and a broken code span."""
    import json
    import shlex

    from dashboard import jobs, ui

    monkeypatch.setenv("WORKBENCH_RUNS", str(tmp_path / "runs"))
    command = ["workbench", "run", "ok", "--option", 'label="a `b` *c*"', "--out", str(tmp_path / "o p")]
    for name, job in (("20260101T000000_ok_a", {"procedure": "ok"}), ("20260101T000001_ok_b", {"command": command})):
        (tmp_path / "runs" / name).mkdir(parents=True)
        (tmp_path / "runs" / name / jobs.JOB_FILE).write_text(json.dumps({**job, "pid": 0}))
        (tmp_path / "runs" / name / jobs.EXIT_FILE).write_text("0")
    at = page("20_run.py")
    assert not at.exception
    captions = texts(at, "caption")
    assert ui.md_escape(shlex.join(command)) in captions, captions
    assert not any("`" in c.replace("\\`", "") for c in captions), captions  # no unescaped backtick
    at.selectbox(key="run.pick").select("20260101T000000_ok_a").run()
    assert not at.exception and not any("`" in c for c in texts(at, "caption"))


def test_run_status_progress_while_running(fake_run):
    import time

    from dashboard import forms, jobs

    folder = jobs.start_run("ok", next(iter(forms.unit_grades().values())), seed=3)
    seen = []
    while not (folder / jobs.EXIT_FILE).exists():
        s = jobs.run_status(folder)
        seen.append((s.state, s.progress))
        time.sleep(0.05)
    final = jobs.run_status(folder)
    assert final.state == "done" and final.progress == 1.0 and final.steps_done == 3
    # progress while running is the recorded share of the planned rig time: 0, 1/3, 2/3, or 0.99 once
    # every step is recorded but the process (the analysis) has not ended
    running = {round(p, 3) for st_, p in seen if st_ == "running" and p is not None}
    assert running <= {0.0, 0.333, 0.667, 0.99} and running & {0.333, 0.667}
    parts = jobs.partial_samples(final.session_dir)
    assert parts is None or len(parts) > 0


def test_no_procedures_installed(seeded_db, monkeypatch):
    from workbench import registry

    monkeypatch.setattr(registry, "procedures", lambda: {})
    at = page("20_run.py")
    assert not at.exception
    assert any("No procedures" in i for i in texts(at, "info"))


# -- Sessions page ---------------------------------------------------------------------
PROFILE = """format: workbench-import/1
sample_rate_hz: 10.0
time: {counter: n}
columns:
  gx: {column: gyr_x, unit: deg/s}
  gy: {column: gyr_y, unit: deg/s}
  gz: {column: gyr_z, unit: deg/s}
  ax: {column: acc_x, unit: g}
  ay: {column: acc_y, unit: g}
  az: {column: acc_z, unit: g}
unit: {serial: IMP-7, model: imported imu}
site: {latitude_deg: 45.0}
sections:
  inline: {flat: [0, 50], nose_up: [50, 100]}
  steps:
    flat: {kind: static, mount: z-down}
    nose_up: {kind: static, mount: x-up}
"""


def _recording_csv(n: int = 100) -> bytes:
    lines = ["n,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z"]
    lines += [f"{i},0.01,0,0,{1.0 if i >= 50 else 0.0},0,{0.0 if i >= 50 else -1.0}" for i in range(n)]
    return ("\n".join(lines) + "\n").encode()


def _import(at: AppTest, data: tuple[str, bytes, str] | list[tuple[str, bytes, str]], profile: str = PROFILE,
            folder: str | None = None) -> AppTest:
    """Upload ``profile`` and the recording: one file, several (``data`` a list), or a typed data ``folder``."""
    at.radio(key="imp.source").set_value("upload").run()
    at.file_uploader(key="imp.profile_upload").set_value(("profile.yaml", profile.encode(), "application/yaml"))
    if folder is not None:
        at.radio(key="imp.from").set_value("data folder").run()
        at.text_input(key="imp.folder").input(folder).run()
    else:
        at.file_uploader(key="imp.data").set_value(data if isinstance(data, list) else [data]).run()
    return at.button(key="imp.go").click().run()


# two streams, one file each (as the MARG recordings, without arrival stamps): accel in g, gyro in deg/s, 100 Hz
STREAMS_PROFILE = """format: workbench-import/1
unit: {serial: IMP-9, model: two-stream board}
site: {latitude_deg: 49.0}
time_base: accel
streams:
  accel:
    file: accelerometer.csv
    time: {column: t_s, unit: s}
    rate_hz: 100
    columns: {ax: {column: ax_g, unit: g}, ay: {column: ay_g, unit: g}, az: {column: az_g, unit: g}}
  gyro:
    file: gyroscope.csv
    time: {column: t_s, unit: s}
    rate_hz: 100
    columns: {gx: {column: gx_dps, unit: deg/s}, gy: {column: gy_dps, unit: deg/s}, gz: {column: gz_dps, unit: deg/s}}
"""


def _stream_files(n: int = 300) -> list[tuple[str, bytes, str]]:
    # values change every sample (a constant value would be read as stale repeats)
    acc = "\n".join(["t_s,ax_g,ay_g,az_g", *(f"{i / 100},{0.001 * (i % 7)},0,1.0" for i in range(n))]) + "\n"
    gyr = "\n".join(["t_s,gx_dps,gy_dps,gz_dps", *(f"{i / 100 + 0.002},{0.01 * (i % 5)},0,0" for i in range(n))]) + "\n"
    return [("accelerometer.csv", acc.encode(), "text/csv"), ("gyroscope.csv", gyr.encode(), "text/csv")]


def _imports(db_tmp: Path) -> list[Path]:
    root = db_tmp / "runs" / "imports"
    return sorted(root.iterdir()) if root.exists() else []


def test_sessions_browse_steps_and_plots(stored_session):
    at = page("30_sessions.py")
    assert not at.exception and not at.error
    assert texts(at, "text")[:2] == ["DASH-001", "multiposition"] and at.metric[0].value == "200"
    steps = at.dataframe[0].value
    # 100 samples at 10 Hz: t_start..t_end = first sample .. last sample + half a sample period = 9.95 s
    assert list(steps["kind"]) == ["static", "static"] and list(steps["duration (s)"]) == [9.95, 9.95]
    at.selectbox(key="sess.step").select("1: static x-up").run()
    assert not at.exception
    assert any("accel (body frame)" in c.value for c in at.caption)
    at.selectbox(key="sess.pick").select("(type a folder)").run()
    assert texts(at, "info") == ["Pick a session above, or type its folder."]  # sessions exist: not 'No sessions yet.'


def test_sessions_long_serial_shown_whole_as_plain_text(seeded_db, tmp_path):
    """A serial is user input: a long one (64 characters, the most a serial may have) is shown whole
    (st.metric cuts it with an ellipsis); markup in the procedure field stays text (st.metric would
    render the bold and the link). A serial holds no markup characters: the session loader refuses them."""
    from dataclasses import replace

    from tests.dashboard.conftest import make_session
    from workbench.session import write_session
    from workbench.values import Unit

    serial = "MARG-MPU6050+HMC5883L-board-7-2026-12-02-rev-C-000123456789-ABCD"
    procedure = "**multiposition** <b>by hand</b> [7](http://x.invalid)"
    session = replace(make_session(), unit=Unit(serial, "test-imu"), procedure=procedure)
    folder = write_session(session, tmp_path / "long")
    seeded_db.add_session(session.id, serial, "test-imu", "multiposition", str(folder), n_steps=2)
    at = page("30_sessions.py")
    assert not at.exception and not at.error
    assert texts(at, "text")[:2] == [serial, procedure]
    assert all(m.label != "Unit" for m in at.metric)


def test_sessions_bad_folder_is_readable(seeded_db, tmp_path):
    at = page("30_sessions.py")
    at.selectbox(key="sess.pick").select("(type a folder)").run()
    at.text_input(key="sess.pick.typed").input(str(tmp_path)).run()
    assert not at.exception
    assert any("no session.json" in e for e in texts(at, "error"))


def test_user_text_in_an_error_is_shown_as_typed_never_as_markdown(seeded_db, tmp_path):
    """A folder named with a link, bold and HTML: the error names it literally (st.error renders Markdown)."""
    typed = tmp_path / "[x](x.invalid)**b** <b>c :red[y]"
    typed.mkdir()
    at = page("30_sessions.py")
    at.selectbox(key="sess.pick").select("(type a folder)").run()
    at.text_input(key="sess.pick.typed").input(str(typed)).run()
    assert not at.exception
    (error,) = [e for e in texts(at, "error") if "no session.json" in e]
    assert "\\[x\\](x.invalid)\\*\\*b\\*\\* \\<b\\>c :red\\[y\\]" in error


def test_md_escape_leaves_plain_text_alone():
    from dashboard import ui

    assert ui.md_escape("sample_rate_hz: 100 Hz (session.json, ±2 °/h)") == "sample_rate_hz: 100 Hz (session.json, ±2 °/h)"
    assert ui.md_escape("a*b`c$d~e\\f") == "a\\*b\\`c\\$d\\~e\\\\f"


def test_sessions_import_through_profile(seeded_db, tmp_path):
    at = _import(page("30_sessions.py"), ("rec.csv", _recording_csv(), "text/csv"))
    assert not at.exception and not at.error, texts(at, "error")
    assert any("Imported into" in s for s in texts(at, "success"))
    (folder,) = _imports(tmp_path)
    sessions = seeded_db.list_sessions("IMP-7")
    assert len(sessions) == 1 and sessions[0].path == str(folder) and sessions[0].n_steps == 2
    # the Browse tab shows the session just imported, without picking it
    assert at.selectbox(key="sess.pick").value.endswith(sessions[0].id[:8])
    assert texts(at, "text")[0] == "IMP-7"


def test_sessions_import_not_a_recording_keeps_nothing(seeded_db, tmp_path):
    at = _import(page("30_sessions.py"), ("rec.csv", b"\x00\x01garbage\xff" * 50, "text/csv"))
    assert not at.exception
    assert any("uploaded rec.csv: not a readable" in e and "recording" in e for e in texts(at, "error")), \
        texts(at, "error")
    assert not texts(at, "success")
    assert _imports(tmp_path) == [] and seeded_db.list_sessions() == []


def test_sessions_import_profile_not_matching_columns(seeded_db, tmp_path):
    at = _import(page("30_sessions.py"), ("rec.csv", _recording_csv(), "text/csv"),
                 profile=PROFILE.replace("gyr_y", "gyro_y"))
    assert not at.exception
    assert any("'gyro_y'" in e for e in texts(at, "error"))
    assert _imports(tmp_path) == [] and seeded_db.list_sessions() == []


def test_sessions_import_multi_stream_upload(seeded_db, tmp_path):
    at = _import(page("30_sessions.py"), _stream_files(), profile=STREAMS_PROFILE)
    assert not at.exception and not at.error, texts(at, "error")
    assert any("reads 2 streams from a data folder: accelerometer.csv, gyroscope.csv" in c.value for c in at.caption)
    (folder,) = _imports(tmp_path)
    sessions = seeded_db.list_sessions("IMP-9")
    assert len(sessions) == 1 and sessions[0].path == str(folder) and sessions[0].n_steps == 1  # one free step
    from workbench.session import load_session

    s = load_session(folder)
    assert len(s.samples) >= 290 and s.options["import"]["streams"].keys() == {"accel", "gyro"}


def test_sessions_import_multi_stream_missing_file_or_one_file_profile(seeded_db, tmp_path):
    at = _import(page("30_sessions.py"), _stream_files()[:1], profile=STREAMS_PROFILE)
    errors = texts(at, "error")
    assert not at.exception and len(errors) == 1
    assert "streams.gyro" in errors[0] and "uploaded gyroscope.csv: no such file" in errors[0], errors
    at = _import(page("30_sessions.py"), _stream_files())  # the single-file profile, two files
    assert any("reads one file, 2 uploaded (accelerometer.csv, gyroscope.csv)" in e for e in texts(at, "error"))
    assert _imports(tmp_path) == [] and seeded_db.list_sessions() == []


def test_sessions_import_data_folder_confined_to_the_roots(seeded_db, tmp_path):
    rec = tmp_path / "runs" / "data" / "board-1"  # the runs folder is a data root by default
    rec.mkdir(parents=True)
    for name, data, _ in _stream_files():
        (rec / name).write_bytes(data)
    at = _import(page("30_sessions.py"), [], profile=STREAMS_PROFILE, folder=str(rec))
    assert not at.exception and not at.error, texts(at, "error")
    (folder,) = _imports(tmp_path)
    assert folder.name.startswith("board-1-") and seeded_db.list_sessions("IMP-9")[0].path == str(folder)
    outside = tmp_path.parent / "elsewhere"
    outside.mkdir(exist_ok=True)
    at = _import(page("30_sessions.py"), [], profile=STREAMS_PROFILE, folder=str(outside))
    errors = texts(at, "error")
    assert len(errors) == 1 and "outside the data roots" in errors[0] and "\n" not in errors[0].split("  \n")[0]
    at = _import(page("30_sessions.py"), [], profile=STREAMS_PROFILE, folder=str(rec / ".." / ".." / ".." / ".."))
    assert any("outside the data roots" in e for e in texts(at, "error"))
    assert len(_imports(tmp_path)) == 1


def test_downsample_keeps_extremes_and_bounds_points():
    import numpy as np
    import pandas as pd

    from dashboard.charts import downsample

    # 4 h at 100 Hz with one spike: the envelope must keep the spike and stay under max_points
    n = 4 * 3600 * 100
    df = pd.DataFrame({"t": np.arange(n) / 100.0, "gx": np.zeros(n)})
    df.loc[777_777, "gx"] = 5.0
    small = downsample(df, max_points=3000)
    assert len(small) <= 3000 and small["gx"].max() == 5.0
    assert small["t"].is_monotonic_increasing and small["t"].iloc[0] == 0.0 and small["t"].iloc[-1] == df["t"].iloc[-1]


# -- helpers the analysis pages use: result_picker / show_result -------------------------------
ANALYSIS_PAGE = """
from dashboard import results
result = results.result_picker("toy", key="toy")
if result is not None:
    results.show_result(result)
"""


@pytest.fixture
def toy_procedure(stored_session, monkeypatch):
    """Procedure ``toy``: mean gyro x over the session (rad/s); fails on option ``fail``."""
    from types import SimpleNamespace

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dashboard import ui
    from workbench import registry
    from workbench.errors import AnalysisError
    from workbench.procedure import ProcedureResult

    def analyze(session, fail=False):
        if fail:
            raise AnalysisError(f"{session.name}: step 1 (static): not enough samples for the toy fit")
        mean = float(session.gyro()[:, 0].mean())
        return ProcedureResult("toy", {"gyro_x_mean": mean}, payload=mean,
                               summary=[f"gyro x mean: {ui.lab(mean, 'deg/h', 1e-6)}"], warnings=["toy warning"])

    def figures(result):
        fig, ax = plt.subplots()
        ax.axhline(result.payload)
        return {"toy_mean": fig}

    toy = SimpleNamespace(NAME="toy", TITLE="toy", DEFAULTS={"fail": False}, analyze=analyze, figures=figures,
                          sequence=None)
    monkeypatch.setattr(registry, "procedures", lambda: {"toy": toy})
    stored = ui.store()
    stored.add_session("sess-toy", "DASH-001", "test-imu", "toy", str(stored_session), n_steps=2)
    return toy


def test_result_picker_analyzes_and_shows_figures(toy_procedure):
    at = AppTest.from_string(ANALYSIS_PAGE, default_timeout=TIMEOUT).run()
    assert not at.exception and not at.error
    # gyro x is 1e-5 rad/s in every sample = 2.063 deg/h (1e-5 * 180/pi * 3600)
    assert any("gyro x mean: 2.063 ± 0.21 °/h" in c.value for c in at.code)
    assert any("toy warning" in w for w in texts(at, "warning"))
    assert len(at.get("image")) == 1  # the one figure of toy's figures(), drawn from the result


def test_result_picker_analysis_error_is_readable(toy_procedure):
    at = AppTest.from_string(ANALYSIS_PAGE, default_timeout=TIMEOUT).run()
    at.checkbox(key="toy.options.toy.fail").check().run()
    assert not at.exception
    assert any("not enough samples for the toy fit" in e for e in texts(at, "error"))


def test_result_picker_without_procedure(seeded_db):
    at = AppTest.from_string(ANALYSIS_PAGE.replace('"toy"', '"not-installed"'), default_timeout=TIMEOUT).run()
    assert not at.exception
    assert any("not installed yet" in i for i in texts(at, "info"))


def test_overview_lists_units_sessions_and_runs(fake_run, stored_session):
    from dashboard import forms, jobs

    folder = jobs.start_run("ok", next(iter(forms.unit_grades().values())))
    _wait_for_end(folder)
    at = page("10_overview.py")
    assert not at.exception and not at.error
    units = at.dataframe[0].value
    assert list(units.serial) == ["DASH-001"] and units.status.iloc[0] == "awaiting approval"
    assert at.dataframe[1].value.procedure.iloc[0] == "multiposition"
    runs = at.dataframe[2].value
    assert runs.state.iloc[0] == "done" and runs.progress.iloc[0] == 100


def test_run_page_in_app_links_to_calibration_sets(fake_run):
    from dashboard import forms, jobs

    _wait_for_end(jobs.start_run("ok", next(iter(forms.unit_grades().values()))))
    at = AppTest.from_file(str(REPO / "app.py"), default_timeout=TIMEOUT).run()
    at.switch_page("dashboard/pages/20_run.py").run()
    assert not at.exception
    assert [link.proto.label for link in at.get("page_link")] == ["Calibration sets →"]


def test_lab_labels_carry_the_lab_unit():
    from dashboard.ui import lab_label

    assert lab_label("gyro_bias_instability_deg_h") == "gyro bias instability (°/h)"
    assert lab_label("settle_tol_c_per_min") == "settle tol (°C/min)"
    assert lab_label("rate_deg_s") == "rate (°/s)" and lab_label("dwell_s") == "dwell (s)"
    assert lab_label("accel_rrw_m_s_h_sqrt_h") == "accel rrw (m/s/h/√h)"
    assert lab_label("positions") == "positions" and lab_label("gap_policy") == "gap policy"


def test_result_picker_opens_the_stored_result_and_reanalyses_only_on_request(toy_procedure, stored_session):
    """A session with a stored result shows that result (summary, options, stored figures), not a re-analysis."""
    from dashboard import ui

    (stored_session.parent / "figures").mkdir(exist_ok=True)
    (stored_session.parent / "figures" / "toy_mean.png").write_bytes(bytes.fromhex(
        "89504e470d0a1a0a0000000d4948445200000001000000010806000000"
        "1f15c4890000000d49444154789c6360000002000154a24f5d0000000049454e44ae426082"))
    ui.store().add_result("toy", "sess-0001", "DASH-001", {"procedure": "toy", "summary": ["stored: 7 °/h"],
                                                               "options": {"fail": False}, "warnings": []})
    calls = []
    analyze = toy_procedure.analyze
    toy_procedure.analyze = lambda session, **o: calls.append(o) or analyze(session, **o)
    at = AppTest.from_string(ANALYSIS_PAGE, default_timeout=TIMEOUT).run()
    assert not at.exception and not at.error
    assert any("stored: 7 °/h" in c.value for c in at.code) and calls == []  # nothing re-analysed
    assert any("fail = false" in c.value for c in at.caption)  # the options it was computed with
    assert len(at.get("image")) == 1  # the stored figure
    button = at.button(key="toy.reanalyse")
    assert button.proto.label == "Re-analyse with: the defaults"
    button.click().run()
    assert not at.exception and len(calls) == 1
    assert any("gyro x mean" in c.value for c in at.code)
    assert any("(not stored)" in i for i in texts(at, "info"))
    assert len(ui.store().list_results("toy")) == 1  # the re-analysis stored nothing


def test_result_picker_stores_an_analysis_on_request(toy_procedure):
    """The button stores the analysis shown (session record and result) through run_analysis; after it the
    page shows the stored result instead of analysing again."""
    from dashboard import ui

    at = AppTest.from_string(ANALYSIS_PAGE, default_timeout=TIMEOUT).run()
    assert ui.store().list_results("toy") == []
    button = at.button(key="toy.store")
    assert button.proto.label == "Store this analysis (the defaults)"
    button.click().run()
    assert not at.exception and not at.error
    rows = ui.store().list_results("toy")
    assert len(rows) == 1 and rows[0]["result"]["gyro_x_mean"] == pytest.approx(1e-5)
    assert any("Stored the toy result" in s for s in texts(at, "success"))
    at.run()
    assert any("Stored result of" in s for s in texts(at, "success"))  # shown as stored, not re-analysed


def test_result_picker_store_failure_stores_nothing(toy_procedure, monkeypatch):
    """A refusal at storing time (here the plausibility gate's error) is one error line; the store is unchanged."""
    from dashboard import ui
    from workbench import procedure
    from workbench.plausibility import ImplausibleCalibration

    def refuse(*args, **kwargs):
        raise ImplausibleCalibration("toy refused: gyro bias x = 8.91e+05 °/h exceeds ±1.08e+05 °/h")

    monkeypatch.setattr(procedure, "analysed", refuse)
    sessions = [r.id for r in ui.store().list_sessions()]
    at = AppTest.from_string(ANALYSIS_PAGE, default_timeout=TIMEOUT).run()
    at.button(key="toy.store").click().run()
    assert not at.exception
    assert any("exceeds ±1.08e+05 °/h" in e for e in texts(at, "error"))
    assert ui.store().list_results("toy") == [] and [r.id for r in ui.store().list_sessions()] == sessions
