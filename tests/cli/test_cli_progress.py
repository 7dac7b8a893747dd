"""CLI output: progress bars know their step total before the first step; no highlighting inside paths."""

from rich.progress import Progress

from workbench.cli import err, out
from workbench.cli.run import _step_totals, _tracker
from workbench.grades import load_spec


def test_progress_bar_shows_the_step_total_from_the_start():
    bar = Progress()
    _tracker(bar, "multiposition", 6)
    assert bar.tasks[0].total == 6 and bar.tasks[0].completed == 0  # "0/6 steps", never "0/None"


def test_campaign_step_totals_come_from_the_sequences():
    from workbench.registry import procedure

    totals = _step_totals(load_spec("industrial_mems"), {})
    assert totals["multiposition"] == len(procedure("multiposition").sequence(load_spec("industrial_mems")).expand())
    assert all(n > 0 for n in totals.values())


def test_consoles_do_not_highlight():
    assert out._highlight is False and err._highlight is False  # digits in /tmp/run-0123 stay uncoloured
