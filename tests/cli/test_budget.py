"""``workbench budget reference-facility`` (workbench/cli/budget.py): paper 003's figures and the verdict."""

from workbench.cli import main


def test_attitude_budget_of_fig_4_and_a_verdict(capsys):
    assert main(["budget", "reference-facility", "--grade", "imu700ca200", "--duration-s", "60"]) == 0
    out = capsys.readouterr().out
    # paper 003 Fig. 4 / eq. 9-10: a 1 m baseline with 2.5 / 5 mm component errors gives 0.144° heading,
    # 0.286° pitch; doubling the errors or halving the baseline doubles them
    assert "0.144 / 0.286" in out and "0.288 / 0.571" in out
    assert "verdict: grade imu700ca200 is" in out


def test_exactly_one_source_of_noise(capsys):
    assert main(["budget", "reference-facility"]) == 2
    assert "give exactly one of --set and --grade" in capsys.readouterr().err
