"""``workbench allan FILE --stat NAME``: the stability family from the command line."""

from pathlib import Path

import numpy as np
import pandas as pd

from workbench.cli import main

REF = Path("/work/shared/data/allantools_reference/phasedat")


def test_one_column_text_file_of_frequencies(tmp_path):
    # the NBS 10-point set as Stable32 reads it (one number per line): SP 1065's values
    data = tmp_path / "nbs10.txt"
    data.write_text("# NBS 10-point set\n" + "\n".join(["892", "809", "823", "798", "671", "644", "883", "903", "677"]))
    out = tmp_path / "oadev.csv"
    assert main(["allan", str(data), "--stat", "oadev", "--rate", "1", "--taus", "1,2", "--out", str(out)]) == 0
    df = pd.read_csv(out)
    assert list(df.columns) == ["column", "tau", "dev", "dev_lo", "dev_hi", "n", "alpha", "edf"]
    np.testing.assert_allclose(df["dev"], [91.22945, 85.95287], rtol=1e-7)
    assert np.all(df["dev_lo"] < df["dev"]) and np.all(df["dev"] < df["dev_hi"])


def test_phase_file_against_stable32_totdev(tmp_path):
    out = tmp_path / "tot.csv"
    assert main(["allan", str(REF / "PHASE.DAT"), "--stat", "totdev", "--data-type", "phase", "--rate", "1",
                 "--taus", "octave", "--confidence", "0.683", "--out", str(out)]) == 0
    df = pd.read_csv(out)
    ref = np.array([[float(v) for v in line.split()] for line in (REF / "phase_dat_totdev_octave.txt").read_text(
        "latin-1").splitlines() if line.strip() and not line.startswith("#")])
    np.testing.assert_array_equal(df["tau"], ref[:, 1])
    np.testing.assert_allclose(df["dev"], ref[:, 5], rtol=5.01e-5)
    np.testing.assert_allclose(df["dev_lo"], ref[:, 4], rtol=0.01)
    np.testing.assert_allclose(df["dev_hi"], ref[:, 6], rtol=0.01)


def test_bad_statistic_and_bad_number_are_one_line_errors(tmp_path, capsys):
    data = tmp_path / "d.txt"
    data.write_text("1\n2\nthree\n")
    assert main(["allan", str(data), "--stat", "oadev", "--rate", "1"]) == 2
    assert "line 3" in capsys.readouterr().err
    data.write_text("1\n2\n3\n4\n5\n")
    assert main(["allan", str(data), "--stat", "xdev", "--rate", "1"]) == 2
    assert "xdev" in capsys.readouterr().err


def test_every_tau_prints_plain_columns_and_equals_the_per_lag_sums(tmp_path, capsys):
    """``--taus all`` on 1000 samples: 250 rows (stop ratio 4: m up to 1000 // 4) printed as aligned text, not a Rich
    table; the one-call kernel equals allantools' per-lag oadev (relative 1e-9)."""
    import allantools

    y = np.random.default_rng(5).standard_normal(1000)
    (tmp_path / "y.txt").write_text("\n".join(map(repr, y.tolist())))
    out = tmp_path / "all.csv"
    assert main(["allan", str(tmp_path / "y.txt"), "--stat", "oadev", "--rate", "2", "--taus", "all",
                 "--out", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].split()[:3] == ["column", "tau", "s"] and sum(s.startswith("data ") for s in lines) == 250
    df = pd.read_csv(out)
    assert df["tau"].tolist() == (np.arange(1, 251) / 2.0).tolist()
    _, ref, _, _ = allantools.oadev(y, 2.0, "freq", np.arange(1, 251) / 2.0)
    np.testing.assert_allclose(df["dev"], ref, rtol=1e-9)
