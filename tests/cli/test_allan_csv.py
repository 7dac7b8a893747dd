"""CSV output of ``workbench allan`` (workbench.cli.allan_csv): rows match the analysis, floats round-trip."""

import csv

import numpy as np

from workbench.analysis.allan_fit import analyze_record
from workbench.cli.allan_csv import CURVE_COLUMNS, curve_rows, write_csv


def test_curve_rows_and_the_file_round_trip(tmp_path):
    rng = np.random.default_rng(8)
    an = analyze_record(1e-3 * rng.standard_normal((20_000, 2)), 100.0, ["c0", "c1"], None, "octave")
    rows = curve_rows(an)
    k = len(an.ci.curve.tau)
    assert len(rows) == 2 * k and all(len(r) == len(CURVE_COLUMNS) for r in rows)
    assert [r[0] for r in rows] == ["c0"] * k + ["c1"] * k
    assert rows[k + 3][4] == an.ci.curve.dev[3, 1] and rows[3][5] <= rows[3][4] <= rows[3][6]
    write_csv(tmp_path / "sub" / "c.csv", CURVE_COLUMNS, rows)
    back = list(csv.reader((tmp_path / "sub" / "c.csv").open()))
    assert tuple(back[0]) == CURVE_COLUMNS and float(back[1 + k + 3][4]) == rows[k + 3][4]  # shortest repr: exact
    assert not list((tmp_path / "sub").glob("*.tmp*"))
