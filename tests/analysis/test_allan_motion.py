"""`allan` refuses a record that moves (hand-held, free step) and analyses a still one (issue 21).

A hand-held record (sim/handheld.py, tumbles of 40-140° in 2 s) must be refused in one line naming the
step and the motion (exit 2 at the command line, nothing written); the same unit left still for the
whole free step is analysed. Still holds of every grade pass (checked for each fixture grade: its
statistic stays under 10x the detector's threshold, which only motion reaches).
"""

import numpy as np
import pytest

import procedures.allan as proc
from workbench.cli import main
from workbench.errors import AnalysisError
from workbench.grades import draw_unit, load_spec
from workbench.session import write_session
from workbench.sim.handheld import handheld_session

UNIT = draw_unit(load_spec("consumer_9axis"), 7)


def test_moving_record_is_refused_naming_step_and_motion():
    session, _ = handheld_session(UNIT, 7, duration_s=30.0, still_s=3.0)
    with pytest.raises(AnalysisError, match=r"step 0 \(free, by hand\): the unit moves: moving \d+% of the time"):
        proc.analyze(session)


def test_still_free_record_is_analysed():
    session, _ = handheld_session(UNIT, 7, duration_s=30.0, still_s=60.0)  # the hand never moves
    result = proc.analyze(session)
    assert "gyro" in result.calibration.noise and result.result["step"] == 0


def test_cli_exit_2_one_line_nothing_written(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{tmp_path}/w.db")
    session, _ = handheld_session(UNIT, 8, duration_s=30.0, still_s=3.0)
    folder = write_session(session, tmp_path / "s")
    before = sorted(p.name for p in folder.iterdir())
    assert main(["analyze", "allan", str(folder)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the unit moves" in err[0] and "Traceback" not in err[0]
    assert sorted(p.name for p in folder.iterdir()) == before


def test_span_still_analyses_the_longest_still_stretch():
    session, truth = handheld_session(UNIT, 9, duration_s=30.0, still_s=20.0)  # 20 s still, a 2-s tumble, still
    with pytest.raises(AnalysisError, match="span=still"):
        proc.analyze(session)
    result = proc.analyze(session, span="still")
    t = session.samples["t"].to_numpy()
    first_move = t[np.argmax(~truth.still)]
    # the stretch ends half a window (0.25 s) or so before the tumble starts
    assert first_move - 1.0 < result.result["duration_s"] <= first_move
    assert result.summary[0].startswith("analysed: the longest still stretch of step 0")
