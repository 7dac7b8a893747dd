"""``workbench allan --method gmwm``: the GMWM fit from the command line, CSV of parameters, bad model."""

import csv

import numpy as np
import pandas as pd

from workbench.analysis.gmwm import parse_model, simulate
from workbench.cli import main


def test_gmwm_command_writes_parameters(tmp_path, capsys):
    # white 1e-4 rad/s/sqrt(Hz) + Gauss-Markov; N from 2^15 samples has a relative sigma ~0.3 %,
    # so the CSV value lies within its own 95 % interval and within 2 % of the truth
    y = simulate(parse_model("wn+gm"), np.array([1e-4, 2e-4, 5.0]), 1 << 15, 0.01, np.random.default_rng(2))
    pd.DataFrame({"gx": y}).to_parquet(tmp_path / "r.parquet")
    out = tmp_path / "p.csv"
    assert main(["allan", str(tmp_path / "r.parquet"), "--rate", "100", "--method", "gmwm", "--processes", "wn+gm",
                 "--bootstrap", "50", "--out", str(out)]) == 0
    rows = {r["parameter"]: r for r in csv.DictReader(out.open())}
    white = rows["white"]
    assert float(white["lo95"]) < float(white["value"]) < float(white["hi95"])
    assert abs(float(white["value"]) / 1e-4 - 1) < 0.02
    assert "gm1_tau_c" in rows and "GMWM wn+gm" in capsys.readouterr().out


def test_gmwm_bad_model_is_one_line_exit_2(tmp_path, capsys):
    pd.DataFrame({"gx": np.zeros(1000)}).to_parquet(tmp_path / "r.parquet")
    assert main(["allan", str(tmp_path / "r.parquet"), "--rate", "100", "--method", "gmwm",
                 "--processes", "wn+xx"]) == 2
    assert main(["allan", str(tmp_path / "r.parquet"), "--rate", "100", "--method", "bayes"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "GMWM model 'wn+xx'" in err[0] and "--method 'bayes'" in err[-1]


def test_large_parquet_is_streamed_automatically(tmp_path, monkeypatch):
    # above STREAM_SAMPLES values the command streams (bounded memory); the curves equal the
    # in-memory ones to summation order (~1e-13 relative)
    import workbench.cli.allan as cli_allan

    y = 1e-3 * np.random.default_rng(5).standard_normal((20_000, 3))
    pd.DataFrame(y, columns=["gx", "gy", "gz"]).to_parquet(tmp_path / "r.parquet")
    args = ["allan", str(tmp_path / "r.parquet"), "--rate", "100"]
    assert main([*args, "--out", str(tmp_path / "mem.csv")]) == 0
    called = []
    real = cli_allan._streamed
    monkeypatch.setattr(cli_allan, "_streamed", lambda *a: called.append(1) or real(*a))
    monkeypatch.setattr(cli_allan, "STREAM_SAMPLES", 10_000)
    assert main([*args, "--out", str(tmp_path / "stream.csv")]) == 0
    assert called
    mem, st = pd.read_csv(tmp_path / "mem.csv"), pd.read_csv(tmp_path / "stream.csv")
    np.testing.assert_allclose(st["adev"], mem["adev"], rtol=1e-10)
