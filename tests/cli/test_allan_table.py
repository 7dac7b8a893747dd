"""``workbench allan`` at 80 columns: the terms table fits, one unit per row, no value split over lines."""

from io import StringIO

import numpy as np
from rich.console import Console

from workbench.analysis.allan_fit import analyze_record
from workbench.cli import out
from workbench.cli.allan import terms_tables


def _render(an, width: int) -> list[str]:
    console = Console(file=StringIO(), width=width, markup=False, highlight=False)
    for t in terms_tables(an, width):
        console.print(t)
    return console.file.getvalue().splitlines()


def test_three_gyro_axes_fit_in_80_columns_in_lab_units():
    # white noise 1e-3 rad/s/sqrt(Hz) at 100 Hz = 3.44 °/√h; the table must show it in °/√h, at most 80 wide
    rng = np.random.default_rng(3)
    y = 1e-3 * np.sqrt(100.0) * rng.standard_normal((60_000, 3))
    an = analyze_record(y, 100.0, ["gx", "gy", "gz"], "gyro", "octave")
    lines = _render(an, 80)
    assert max(len(line.rstrip()) for line in lines) <= 80
    header = next(line for line in lines if line.lstrip().startswith("term"))
    assert header.split()[:5] == ["term", "unit", "gx", "gy", "gz"]  # all three axes in one table
    white = next(line for line in lines if line.lstrip().startswith("N ") and "°/√h" in line)
    assert white.split()[1] == "°/√h" and abs(float(white.split()[2]) - 3.44) < 0.1


def test_many_columns_fold_into_several_tables_of_80():
    rng = np.random.default_rng(4)
    an = analyze_record(1e-3 * rng.standard_normal((20_000, 6)), 100.0, [f"c{i}" for i in range(6)], None, "decade")
    lines = _render(an, 80)
    assert max(len(line.rstrip()) for line in lines) <= 80
    assert sum(line.lstrip().startswith("term") for line in lines) >= 2
    assert all(any(f"c{i}" in line for line in lines) for i in range(6))


def test_long_paths_are_not_broken_by_rich(capsys, monkeypatch):
    monkeypatch.setattr(out, "_width", 80)
    path = "/tmp/" + "/".join(f"run-{i:04d}" for i in range(20)) + "/result.json"  # 200 characters
    out.print(f"results in {path} (result.json, calibration.json, figures/)")
    lines = capsys.readouterr().out.splitlines()
    assert path in lines  # whole, on a line of its own, never folded mid-path
    assert all(len(line) <= 80 for line in lines if line != path)  # the words around it still wrap
