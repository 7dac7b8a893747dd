"""Simulated fleets: N units of one grade, each with its own seed, recorded by one procedure."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from workbench.confine import safe_component
from workbench.grades import draw_unit, load_spec
from workbench.jobs import record_procedure
from workbench.registry import procedure as get_procedure
from workbench.rigconfig import load_rig_config


def simulate_fleet(grade: str, units: int, procedure: str, out_dir: Path, seed0: int = 1, rig: str = "sim",
                   options: dict | None = None, progress: Callable[[int, int, Path], None] | None = None) -> list[Path]:
    """Record ``procedure`` for ``units`` simulated units of ``grade`` (seeds ``seed0 + k``).

    Sessions go to ``out_dir/<serial>/`` (with ``truth.json``); returns their folders.
    """
    spec, proc, cfg = load_spec(grade), get_procedure(procedure), load_rig_config(rig)
    out_dir = Path(out_dir)
    dirs = []
    for k in range(units):
        seed = seed0 + k
        truth = draw_unit(spec, seed, serial=f"{spec.name}-{seed:05d}")
        d = out_dir / safe_component(truth.serial, f"grade {spec.name}: serial")
        record_procedure(proc, spec, truth, cfg, seed, d, options)
        dirs.append(d)
        if progress is not None:
            progress(k + 1, units, d)
    return dirs
