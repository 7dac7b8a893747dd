"""Figures saved by two processes are the same files as saved by one, and a process forked after
``prepare_drawing`` loads nothing more to draw and save its first figure (workbench/plots/pool.py)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from workbench.errors import SessionError  # noqa: E402
from workbench.plots.pool import MANY, save_figures  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


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


_FIRST_SAVE = """
import sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.mathtext import MathTextParser
from workbench.plots.pool import prepare_drawing
if sys.argv[1] == "prepared":
    prepare_drawing()
before, parser = set(sys.modules), MathTextParser._parser
fig, ax = plt.subplots(figsize=(4, 3))
ax.semilogy([1, 2, 3], [1, 10, 100])
fig.savefig(sys.argv[2], dpi=110)
new = sorted(m for m in set(sys.modules) - before if m.split(".")[0] in ("matplotlib", "PIL"))
print(" ".join(new), "parser-built" if parser is None and MathTextParser._parser is not None else "")
"""


def test_prepared_drawing_leaves_the_first_figure_nothing_to_load(tmp_path):
    # what prepare_drawing loads before the campaign's workers fork is then loaded once, not per worker
    def first_save(mode: str) -> str:
        p = subprocess.run([sys.executable, "-c", _FIRST_SAVE, mode, str(tmp_path / f"{mode}.png")],
                           capture_output=True, text=True, timeout=300, env={**os.environ, "PYTHONPATH": str(ROOT)})
        assert p.returncode == 0, p.stderr[-2000:]
        return p.stdout.strip()

    cold = first_save("cold")
    assert "backend_agg" in cold and "PIL." in cold and "parser-built" in cold  # the check sees the loading
    assert first_save("prepared") == ""
