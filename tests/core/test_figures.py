"""Figures: drawn once at their own size (margins fitted once as drawn, no re-fit on save), or not at all."""

from __future__ import annotations

import struct

from workbench.grades import draw_unit, load_spec
from workbench.jobs import record_procedure
from workbench.procedure import run_analysis
from workbench.registry import procedure
from workbench.rigconfig import load_rig_config
from workbench.store import Store
from workbench.stored import stored_figures


def _png_size(path) -> tuple[int, int]:
    with open(path, "rb") as f:
        head = f.read(24)
    return struct.unpack(">II", head[16:24])


def test_figures_at_their_own_size_and_none_on_request(tmp_path):
    proc = procedure("multiposition")
    spec = load_spec("industrial_mems")
    session = record_procedure(proc, spec, draw_unit(spec, 4), load_rig_config("sim"), 4, None)
    run_analysis(proc, session, {}, tmp_path / "none", None, figures=False)
    assert (tmp_path / "none" / "result.json").exists() and not (tmp_path / "none" / "figures").exists()
    run_analysis(proc, session, {}, tmp_path / "all", store := Store(f"sqlite:///{tmp_path / 'store.db'}"))
    pngs = sorted((tmp_path / "all" / "figures").glob("*.png"))
    assert pngs
    stored = store.list_results("multiposition")[0]["result"]  # names the folder the figures went to
    assert stored_figures(session.path, stored) == pngs
    figs = proc.figures(run_analysis(proc, session, {}, None, None))
    for png in pngs:
        fig = figs[png.stem]
        w, h = fig.get_size_inches() * 110  # the dpi of write_outputs
        assert _png_size(png) == (round(w), round(h))  # not cropped by a tight bounding box
