"""``workbench allan FILE``: a column with a non-numeric cell is refused, naming file and column (issue 16)."""

import numpy as np
import pandas as pd
import pytest

from workbench.cli import main


@pytest.mark.parametrize("columns", [[], ["--columns", "gx,gy"]])
def test_a_non_numeric_cell_is_refused_not_dropped(tmp_path, capsys, columns):
    y = 1e-4 * np.random.default_rng(4).standard_normal((2_000, 2))
    rows = [f"{i * 0.01:.2f},{a:.6e},{b:.6e}" for i, (a, b) in enumerate(y)]
    rows[1500] = "15.00,1e-4,abc"  # one bad cell in gy
    src = tmp_path / "rec.csv"
    src.write_text("t,gx,gy\n" + "\n".join(rows) + "\n")
    assert main(["allan", str(src), *columns]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "rec.csv: column gy: non-numeric cell 'abc' at row 1501" in err[0]


def test_numeric_columns_still_analysed(tmp_path, capsys):
    y = 1e-4 * np.random.default_rng(4).standard_normal(2_000)
    pd.DataFrame({"t": np.arange(2_000) * 0.01, "gx": y}).to_csv(tmp_path / "ok.csv", index=False)
    assert main(["allan", str(tmp_path / "ok.csv"), "--taus", "decade"]) == 0
