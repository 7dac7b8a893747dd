"""CLI output: progress bars know their step total before the first step and never stand before an error
line; no highlighting inside paths."""

import pytest
from rich.progress import Progress, TextColumn

from workbench.cli import err, main, out, progress_bar
from workbench.cli.run import _campaign_plans, _tracker
from workbench.errors import WorkbenchError
from workbench.grades import load_spec
from workbench.rigconfig import load_rig_config


def test_progress_bar_shows_the_step_total_from_the_start():
    bar = Progress()
    _tracker(bar, "multiposition", 6)
    assert bar.tasks[0].total == 6 and bar.tasks[0].completed == 0  # "0/6 steps", never "0/None"


def test_campaign_step_totals_come_from_the_sequences():
    from workbench.registry import procedure

    plans = _campaign_plans(load_spec("industrial_mems"), load_rig_config("sim"), {})
    assert len(plans["multiposition"].expand()) == \
        len(procedure("multiposition").sequence(load_spec("industrial_mems")).expand())
    assert all(len(seq.expand()) > 0 for seq in plans.values())


@pytest.mark.parametrize("args", [
    ["run", "carousel", "-o", "rate_deg_s=5000"],  # 5000 °/s on a 1000 °/s table
    ["run", "campaign", "-o", "allan.duration_s=1e15"],  # a record no memory holds
    ["simulate-fleet", "--grade", "industrial_mems", "--units", "2", "--procedure", "carousel",
     "-o", "rate_deg_s=5000"],
])
def test_a_rig_limit_refusal_is_the_one_line_on_stderr(tmp_path, capsys, monkeypatch, args):
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{tmp_path}/w.db")
    assert main([*args, "--out", str(tmp_path / "o")]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and ("exceeds the limit" in lines[0] or "in this machine's memory" in lines[0]), lines
    assert not (tmp_path / "o").exists()


def test_a_command_failing_under_its_progress_bar_leaves_only_its_error(capsys):
    with pytest.raises(WorkbenchError), progress_bar(TextColumn("{task.description}")) as bar:
        bar.add_task("recording", total=6)
        raise WorkbenchError("rig: cannot open")
    assert capsys.readouterr().err == ""
    with progress_bar(TextColumn("{task.description}")) as bar:  # a bar that finishes stays
        bar.add_task("recording", total=6)
    assert "recording" in capsys.readouterr().err


def test_campaign_options_for_a_procedure_it_does_not_run_are_refused(tmp_path, capsys):
    # carousel is not a campaign procedure: its option was silently ignored
    assert main(["run", "campaign", "--no-store", "-o", "carousel.rate_deg_s=50", "--out", str(tmp_path / "o")]) == 2
    err_text = capsys.readouterr().err
    assert "carousel is not in the campaign of grade industrial_mems" in err_text and not (tmp_path / "o").exists()


def test_consoles_do_not_highlight():
    assert out._highlight is False and err._highlight is False  # digits in /tmp/run-0123 stay uncoloured
