"""Figures saved by two processes are the same files as saved by one (workbench/plots/pool.py)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from workbench.errors import SessionError  # noqa: E402
from workbench.plots.pool import MANY, save_figures  # noqa: E402


def _figures(n: int) -> dict:
    rng = np.random.default_rng(5)
    out = {}
    for i in range(n):
        fig, ax = plt.subplots(figsize=(4, 3), layout="constrained")
        ax.plot(rng.standard_normal(200).cumsum(), label=f"axis {i}")
        ax.set(xlabel="time [s]", ylabel="bias [°/h]", title=f"figure {i}")
        ax.legend()
        out[f"fig{i}"] = fig
    return out


def test_two_processes_write_the_same_pngs_as_one(tmp_path):
    n = MANY + 1
    plt.close("all")  # figures other tests left open
    one = save_figures(_figures(n), tmp_path / "one", workers=1)
    two = save_figures(_figures(n), tmp_path / "two", workers=2)
    assert [p.name for p in one] == [p.name for p in two] == [f"fig{i}.png" for i in range(n)]
    for a, b in zip(one, two):
        assert a.read_bytes() == b.read_bytes()
    assert not list((tmp_path / "two").glob(".*"))  # no temporary file left
    assert plt.get_fignums() == []  # every figure closed


def test_a_figure_that_fails_in_the_second_process_is_raised_here(tmp_path):
    plt.close("all")
    figs = _figures(MANY)

    def fail(*args, **kwargs):
        raise SessionError("fig1: cannot draw")

    figs["fig1"].savefig = fail  # drawn by the second process (every other figure)
    with pytest.raises(SessionError, match="fig1: cannot draw"):
        save_figures(figs, tmp_path, workers=2)
    assert plt.get_fignums() == []
