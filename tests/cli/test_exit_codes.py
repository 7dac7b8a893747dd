"""Exit codes and usage errors at the CLI edge (issue 16): one line on stderr, exit 2, no traceback."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from workbench.cli import main

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def db(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{tmp_path}/w.db")


@pytest.mark.parametrize("args,match", [
    (["run"], "Missing argument 'PROCEDURE'"),
    (["frobnicate"], "No such command 'frobnicate'"),
    (["run", "multiposition", "--unit"], "'--unit' requires an argument"),
    (["run", "multiposition", "--seed", "x"], "'--seed'"),
    (["run", "multiposition", "--bogus"], "No such option: --bogus"),
    (["sets", "list", "--format", "xx"], "--format 'xx'"),
    (["run", "multiposition", "-o", "dwell_s=abc", "--dry-run"], "--option dwell_s='abc': expected a number"),
    (["run", "multiposition", "-o", "dwell_s=NaN", "--dry-run"], "--option dwell_s=nan: expected a number"),
    (["allan"], "Missing argument"),
])
def test_usage_error_is_one_line_and_exit_2(db, capsys, args, match):
    assert main(args) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and match in lines[0] and "Traceback" not in captured.err


def test_usage_error_of_the_installed_console_script_has_no_traceback(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "WORKBENCH_DB": f"sqlite:///{tmp_path}/w.db"}
    p = subprocess.run([sys.executable, "-m", "workbench", "sets", "list", "--format", "xx"], env=env,
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and "Traceback" not in p.stderr


def test_version_and_help_exit_0(capsys):
    assert main(["--version"]) == 0 and "workbench" in capsys.readouterr().out
    assert main(["run", "--help"]) == 0


def test_batch_with_failed_sessions_exits_non_zero(db, tmp_path, capsys):
    bad = tmp_path / "not-a-session"
    bad.mkdir()
    assert main(["batch", "multiposition", str(bad), "--scheduler", "serial", "--no-store"]) == 1
    assert "0 analysed, 1 failed" in capsys.readouterr().out


def _steps(session: Path) -> int:
    """Steps recorded so far (the runner's step log)."""
    from workbench.session import step_log

    return len(step_log(session))


def test_ctrl_c_exits_130_after_making_the_rig_safe_and_the_hint_resumes(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "WORKBENCH_DB": f"sqlite:///{tmp_path}/w.db"}
    out = tmp_path / "mp"
    cmd = [sys.executable, "-m", "workbench", "run", "multiposition", "--out", str(out), "-o", "dwell_s=20"]
    p = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    deadline = time.time() + 120
    while time.time() < deadline and _steps(out / "session") < 2 and p.poll() is None:
        time.sleep(0.05)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    if p.returncode == 0:
        pytest.skip("the run finished before Ctrl-C")
    assert p.returncode == 130 and "Traceback" not in err
    assert "the rig was made safe" in err
    hint = err.split("Continue with: ", 1)[1].split()
    assert hint[:4] == ["workbench", "run", "multiposition", "--resume"]
    # the hint is a command that works: run it
    resumed = subprocess.run([sys.executable, "-m", *hint], env=env, capture_output=True, text=True, cwd=tmp_path,
                             timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    assert json.loads((out / "session" / "session.json").read_text())["complete"]
    assert (out / "result.json").exists()


def test_a_constant_record_is_one_line_naming_the_file_and_column(db, tmp_path, capsys):
    """A stuck channel (every sample equal) has no noise to identify: exit 2 naming it, no traceback."""
    path = tmp_path / "stuck.txt"
    path.write_text("3.0\n" * 1000)
    assert main(["allan", str(path), "--rate", "10"]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in captured.err
    assert f"{path}: column data: the deviation is zero at every tau" in lines[0]


def _one_line(capsys) -> str:
    """The single stderr line of a refused command (no traceback)."""
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in captured.err, captured.err
    return lines[0]


@pytest.mark.parametrize("name,text,args,match", [
    ("header.csv", "t,gx\n", [], "0 sample(s): too few to find the sample rate from the time column"),
    ("header.csv", "t,gx\n", ["--rate", "10"], "0 usable samples"),
    ("t_only.csv", "t\n0\n0.1\n0.2\n", [], "no rate column besides t, time and step"),
    ("t_only.csv", "t\n0\n0.1\n0.2\n", ["--stat", "adev"], "no rate column besides t, time and step"),
    # +-1e308 overflows the deviation to NaN, which read as "a constant record"
    ("huge.txt", "1e308\n-1e308\n" * 500, ["--rate", "10"], "column data: value 1e+308 at row 1 is beyond ±1e+100"),
    ("huge.txt", "1e308\n-1e308\n" * 500, ["--rate", "10", "--stat", "adev", "--data-type", "phase"],
     "column data: value 1e+308 at row 1"),
])
def test_a_degenerate_allan_record_is_one_line_naming_it(db, tmp_path, capsys, name, text, args, match):
    path = tmp_path / name
    path.write_text(text)
    assert main(["allan", str(path), *args]) == 2
    assert f"{path}: {match}" in _one_line(capsys)


@pytest.mark.parametrize("rate", ["0", "-5", "nan", "inf", "1e308", "1e-308"])
@pytest.mark.parametrize("stat", [[], ["--stat", "oadev"]])
def test_an_allan_rate_out_of_range_is_refused_before_the_record_is_read(db, tmp_path, capsys, rate, stat):
    path = tmp_path / "x.txt"
    path.write_text("".join(f"{(-1) ** k * 0.001 * (k % 7)}\n" for k in range(1000)))
    assert main(["allan", str(path), "--rate", rate, *stat]) == 2
    assert _one_line(capsys).startswith(f"error: --rate {float(rate)!r}: expected a sample rate in 1e-06..1e+07 Hz")


@pytest.mark.parametrize("args,match", [
    (["run", "multiposition", "--seed", "-1", "--dry-run"], "Invalid value for '--seed'"),  # was a SeedSequence traceback
    (["simulate-fleet", "--procedure", "multiposition", "--grade", "industrial_mems", "--out", "x", "--units", "0"],
     "Invalid value for '--units'"),  # was exit 0 with nothing done
    (["batch", "multiposition", ".", "--workers", "0"], "Invalid value for '--workers'"),  # a cluster of 0 workers hung
])
def test_a_count_or_seed_out_of_range_is_a_usage_error(db, capsys, args, match):
    assert main(args) == 2
    assert match in _one_line(capsys)


def test_a_step_too_long_for_memory_is_refused_before_anything_is_written(db, tmp_path, capsys):
    """A dwell of 1e12 s at 100 Hz (1e14 samples) was a MemoryError traceback after the session folder was made."""
    assert main(["run", "multiposition", "-o", "dwell_s=1e12", "--dry-run"]) == 2
    assert "step 0 (static, x-up): 1e+12 s at 100 Hz is 1e+14 samples; a step's record holds at most" in _one_line(capsys)
    out = tmp_path / "long"
    assert main(["run", "allan", "-o", "duration_s=1e15", "-o", "soak=false", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "1e+17 samples" in err.strip().splitlines()[-1]
    assert not out.exists()


def test_an_out_path_that_cannot_be_written_is_one_line(db, tmp_path, capsys):
    """run --out an existing file, sets export --out a folder, allan --plot where no file can be made."""
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    assert main(["run", "multiposition", "-o", "dwell_s=2", "--no-store", "--out", str(a_file)]) == 2
    assert "a_file is a file; --out names a folder" in _one_line(capsys)
    from tests.core.test_store import a_set

    s = a_set().save(tmp_path / "s.json")
    assert main(["sets", "export", str(s), "--out", str(tmp_path)]) == 2
    assert f"{tmp_path}: cannot write (is a folder)" in _one_line(capsys)
    rec = tmp_path / "r.txt"
    rec.write_text("".join(f"{(-1) ** k * 0.001 * (k % 7)}\n" for k in range(1000)))
    assert main(["allan", str(rec), "--rate", "10", "--plot", str(a_file / "x.png")]) == 2
    assert f"--plot {a_file / 'x.png'}: cannot write" in capsys.readouterr().err.strip().splitlines()[-1]


def test_an_output_folder_under_a_file_is_one_line(db, tmp_path, capsys):
    """run --out a_file/x (the session folder) and analyze --figures a_file (result folder) were
    NotADirectoryError / FileExistsError tracebacks after the work was done."""
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    assert main(["run", "multiposition", "-o", "dwell_s=2", "--no-store", "--no-figures",
                 "--out", str(a_file / "x")]) == 2
    assert f"{a_file / 'x' / 'session'}: cannot make the session folder (Not a directory)" in _one_line(capsys)
    from workbench.jobs import simulate
    from workbench.registry import procedure

    simulate(procedure("multiposition").sequence("industrial_mems", dwell_s=2.0), "industrial_mems", 1,
             tmp_path / "s", procedure="multiposition")
    assert main(["analyze", "multiposition", str(tmp_path / "s"), "--no-store", "--figures", str(a_file)]) == 2
    assert f"{a_file}: cannot make the output folder (File exists)" in _one_line(capsys)


@pytest.mark.parametrize("args,match", [
    (["run", "multiposition", "--unit", "", "--dry-run"], "empty grade name (known grades: "),
    (["run", "multiposition", "--rig", " ", "--dry-run"], "empty rig name (known: "),
    (["rig", "check", ""], "empty rig name (known: "),
    # the hardware-in-the-loop server: refused before any port opens (were a KeyError traceback, a motion
    # engine dead of int(nan), an immediate exit 0, a server that never stops)
    (["rig", "hil", "sim", "--seconds", "1"], "rig sim-turntable: not a hardware-in-the-loop configuration"),
    (["rig", "hil", "hil", "--speed", "nan", "--seconds", "1"], "hil speed nan: expected simulated seconds"),
    (["rig", "hil", "hil", "--speed", "1e308", "--seconds", "1"], "hil speed 1e+308: expected"),
    (["rig", "hil", "hil", "--seconds", "-5"], "--seconds -5: expected a positive number"),
    (["rig", "hil", "hil", "--seconds", "nan"], "--seconds nan: expected a positive number"),
    # under the batch's progress bar: the bar is cleared, the list names every scheduler the help offers
    (["batch", "multiposition", "x", "--no-store", "--scheduler", "bogus"], "expected 'local', 'serial' or tcp://"),
    # option values: a non-finite number anywhere in a list, and tilts that are not [roll, pitch] pairs
    # (were reshape / conversion tracebacks in the magnetometer sequence)
    (["run", "magnetometer", "-o", "tilts_deg=[[0, 1e400]]", "--dry-run"], "tilts_deg=[[0, inf]]: holds a number that is not finite"),
    (["run", "magnetometer", "-o", "tilts_deg=[30]", "--dry-run"], "tilts_deg=[30]: expected [roll, pitch] pairs"),
    (["run", "magnetometer", "-o", 'tilts_deg=[[30, "a"]]', "--dry-run"], "expected [roll, pitch] pairs in degrees"),
    (["run", "magnetometer", "-o", "tilts_deg=[[1e10, 0]]", "--dry-run"], "each within ±180"),
    (["run", "ahrs-table", "-o", 'mounts=[[1, "a"]]', "--dry-run"], "must be a list of [roll, pitch] pairs"),
    # counts of turns, laps, pairs and holds are bounded: turns=1e30 built its sequence for ever
    (["run", "earth-rate", "-o", "turns=1e30", "--dry-run"], "earth-rate: turns=1e+30 must be <= 1000"),
    (["run", "earth-rate", "-o", "step_deg=1e-30", "--dry-run"], "earth-rate: step_deg=1e-30 (deg) must be >= 0.1 deg"),
    (["run", "rate", "-o", 'rates_fs=[[1, "a"]]', "--dry-run"], "rates_fs=[[1, 'a']]: expected a list of fractions"),
    (["run", "zupt-alignment", "-o", "positions=[30]", "--dry-run"], "positions=[30]: expected [mount, table angle"),
    (["run", "zupt-alignment", "-o", "positions=[[]]", "--dry-run"], "expected [mount, table angle °] pairs"),
    (["run", "carousel", "-o", "laps=1e12", "--dry-run"], "carousel: laps=1000000000000.0 must be <= 1000"),
    (["run", "maytagging", "-o", "count=1e9", "--dry-run"], "maytagging: count=1000000000.0 must be <= 10000"),
    (["run", "redundant", "-o", "turns=1e9", "--dry-run"], "redundant: turns=1000000000.0 must be <= 1000"),
    (["run", "magnetometer", "-o", "yaw_steps=1e9", "--dry-run"], "magnetometer: yaw_steps=1000000000.0 must be <= 3600"),
    (["run", "zupt-alignment", "-o", "turns=1e9", "--dry-run"], "turns=1000000000.0 must be <= 1000"),
])
def test_a_blank_grade_or_rig_name_or_a_bad_hil_setting_says_so(db, capsys, args, match):
    assert main(args) == 2
    assert match in _one_line(capsys)  # were '.../fixtures/units/.yaml: no such ...' and '.: no such ...'


@pytest.mark.parametrize("bias", ['[[1, "a"]]', "[1, 2]"])
def test_a_north_finding_bias_that_is_not_three_numbers_is_one_line(db, tmp_path, capsys, bias):
    from workbench.grades import load_spec
    from workbench.jobs import simulate
    from workbench.registry import procedure

    simulate(procedure("maytagging").sequence(load_spec("industrial_mems"), count=4, dwell_s=5.0), "industrial_mems",
             1, tmp_path / "s", procedure="maytagging")
    assert main(["analyze", "maytagging", str(tmp_path / "s"), "--no-store", "-o", f"bias={bias}"]) == 2
    assert "maytagging: bias=" in _one_line(capsys)  # [[1, "a"]] was a ValueError traceback


def test_an_empty_set_reference_says_so(db, capsys):
    """Was '.: cannot read (Is a directory)': an empty argument read as the current folder."""
    assert main(["sets", "show", ""]) == 2
    assert "empty set reference: give a set id (or prefix) or a calibration file" in _one_line(capsys)


def test_a_thermal_sweep_of_absurdly_many_soaks_is_one_line(db, capsys):
    """step_c=1e-9 °C over -10..50 °C: 6e10 setpoints, a 447 GiB MemoryError traceback before."""
    assert main(["run", "thermal", "--dry-run", "-o", "step_c=1e-9"]) == 2
    assert "thermal: step_c=1e-09 °C makes 6e+10 soaks from -10 to 50 °C; at most 1000" in _one_line(capsys)


@pytest.mark.parametrize("args,match", [
    (["run", "thermal", "--dry-run", "-o", "order=abc"], "thermal: order='abc' is not a whole number"),
    (["run", "thermal", "--dry-run", "-o", "order=-1"], "thermal: order=-1 must be >= 0"),  # both were tracebacks
    (["run", "allan", "--dry-run", "-o", "mount=[[1,2],[3]]"], "mount: not a 3x3 rotation matrix"),  # ragged list
])
def test_an_option_value_of_the_wrong_shape_is_one_line(db, capsys, args, match):
    assert main(args) == 2
    assert match in _one_line(capsys)


def test_allan_taus_holding_text_is_one_line(db, tmp_path, capsys):
    """-o taus='[1, "a"]' reached np.asarray(taus, float): a ValueError traceback."""
    from workbench.analysis.allan import averaging_factors
    from workbench.errors import AnalysisError

    with pytest.raises(AnalysisError, match="taus \\[1, 'a'\\]: expected octave, decade, <k>-per-decade or a list"):
        averaging_factors(1000, [1, "a"], 100.0)


@pytest.mark.parametrize("args,match", [
    # multiposition recorded its whole sequence, then its analysis refused the unknown option 'calibration'
    (["run", "multiposition", "--calibration", "any.json"],
     "multiposition: --calibration is for validations; multiposition takes none"),
    (["run", "campaign", "--calibration", "any.json", "--dry-run"],
     "campaign: --calibration is for validations; a campaign produces the calibration"),
    # a dry run of a validation read nothing: an empty or unknown set passed as 'within the limits'
    (["run", "ahrs-table", "--calibration", "", "--dry-run"], "empty set reference"),
    (["run", "ahrs-table", "--calibration", "nosuch", "--dry-run"], "set 'nosuch' is not in the store"),
    (["run", "lns-dead-reckoning", "--unit", "quasi_tactical", "--calibration", "nosuch", "--dry-run"],
     "set 'nosuch' is not in the store"),
])
def test_calibration_is_read_before_anything_is_recorded(db, tmp_path, monkeypatch, capsys, args, match):
    monkeypatch.chdir(tmp_path)
    assert main(args) == 2
    assert match in _one_line(capsys)
    assert not (tmp_path / "runs").exists()  # nothing recorded


def test_resume_of_a_recording_interrupted_in_its_analysis_analyses_it(db, tmp_path):
    """Ctrl-C after the last step reached the disk (during the analysis) prints the resume hint; the
    hint must finish the job, not answer 'the session is already complete' (exit 2, as CI once saw)."""
    out = tmp_path / "mp"
    assert main(["run", "multiposition", "--out", str(out), "-o", "dwell_s=2", "--no-store"]) == 0
    (out / "result.json").unlink()  # as if interrupted before the analysis wrote it
    assert json.loads((out / "session" / "session.json").read_text())["complete"]
    assert main(["run", "multiposition", "--resume", str(out / "session"), "--no-store"]) == 0
    assert (out / "result.json").exists()
