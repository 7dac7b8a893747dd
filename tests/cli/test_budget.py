"""``workbench budget reference-facility`` (workbench/cli/budget.py): paper 003's figures and the verdict."""

import pytest

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


@pytest.mark.parametrize("option,value,match", [
    ("--duration-s", "1e12", "--duration-s 1e+12: expected 10 to 86400 s"),  # ran for ever
    ("--duration-s", "nan", "--duration-s nan: expected 10 to 86400 s"),
    ("--ppr-cm", "-1", "--ppr-cm -1: expected a positive finite number"),  # was a verdict, exit 0
    ("--ppr-cm", "nan", "--ppr-cm nan"),
    ("--tilt-deg", "inf", "--tilt-deg inf"),  # was RuntimeWarnings and a verdict from NaN covariances
    ("--position-req-cm", "0", "--position-req-cm 0"),
])
def test_an_option_out_of_range_is_one_line_before_any_work(capsys, option, value, match):
    assert main(["budget", "reference-facility", "--grade", "imu700ca200", option, value]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and match in err, err
