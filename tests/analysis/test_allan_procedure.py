"""The ``allan`` procedure on the simulated rig, the ``workbench allan`` command and the Kalibr export."""

import numpy as np
import pandas as pd
import pytest
import yaml

from workbench import registry
from workbench.analysis.allan import deviation
from workbench.cli import main
from workbench.jobs import simulate


@pytest.fixture(scope="module")
def result():
    proc = registry.procedure("allan")
    seq = proc.sequence(None, duration_s=1200.0, soak=False)
    session, truth = simulate(seq, "industrial_mems", seed=5)
    return proc, proc.analyze(session), truth


def test_sequence_soaks_then_holds():
    seq = registry.procedure("allan").sequence(None, duration_s=3600.0, temperature_c=40.0)
    kinds = [s.kind for s in seq.expand()]
    assert kinds[0] == "soak" and kinds[-1] == "static"
    assert seq.expand()[-1].duration_s == 3600.0 and seq.expand()[0].temperature_c == 40.0


def test_noise_block_against_truth(result):
    proc, res, truth = result
    cal = res.calibration.to_dict()  # schema-valid
    for triad, term in (("gyro", "arw"), ("accel", "vrw")):
        # 120k samples: white density 1-sigma ~0.5 % (single-point bound); 5 % is ~10 sigma and
        # leaves room for the bias-instability share at the short taus
        np.testing.assert_allclose(cal["noise"][triad][term], truth.noise_of(triad).white, rtol=0.05)
        assert len(cal["noise"][triad][term + "_ci95"]) == 3
    assert res.summary and "°/√h" in res.summary[0]
    figs = proc.figures(res)
    assert set(figs) == {"adev"} and len(figs["adev"].axes) == 2


def test_kalibr_export(result):
    _, res, _ = result
    exp = registry.exporter("kalibr").export(res.calibration)
    doc = yaml.safe_load(exp.text)
    arw = res.calibration.noise_term("gyro", "arw")
    assert doc["gyroscope_noise_density"] == pytest.approx(arw.max(), rel=1e-6)
    assert doc["update_rate"] == 100
    assert any("bias_instability" in d for d in exp.dropped)
    assert doc["gyroscope_random_walk"] > 0 and doc["accelerometer_random_walk"] > 0


def test_cli_on_plain_csv(tmp_path):
    y = 1e-4 * np.random.default_rng(3).standard_normal((20_000, 3))
    src = tmp_path / "rates.csv"
    pd.DataFrame(y, columns=["gx", "gy", "gz"]).to_csv(src, index=False)
    out, png = tmp_path / "curves.csv", tmp_path / "adev.png"
    assert main(["allan", str(src), "--rate", "200", "--taus", "decade", "--out", str(out), "--plot", str(png)]) == 0
    curves = pd.read_csv(out)
    ref = deviation(y, 200.0, "oadev", "decade")
    assert len(curves) == 3 * len(ref.tau)
    gy = curves[curves.column == "gy"]
    np.testing.assert_allclose(gy.adev, ref.dev[:, 1], rtol=1e-12)
    assert np.all((gy.adev_lo95 < gy.adev) & (gy.adev < gy.adev_hi95))
    assert png.stat().st_size > 10_000


def test_cli_bad_inputs(tmp_path, capsys):
    y = 1e-4 * np.random.default_rng(4).standard_normal((5_000, 1))
    df = pd.DataFrame({"t": np.arange(5_000) * 0.01, "gx": y[:, 0]})
    df.loc[2_000:, "t"] += 0.004  # one interval of 0.014 s: not a gap, not the nominal rate
    src = tmp_path / "jitter.csv"
    df.to_csv(src, index=False)
    assert main(["allan", str(src)]) == 2
    assert "non-constant sample rate" in capsys.readouterr().err
    src2 = tmp_path / "norate.csv"
    df[["gx"]].to_csv(src2, index=False)
    assert main(["allan", str(src2)]) == 2
    assert "--rate" in capsys.readouterr().err
