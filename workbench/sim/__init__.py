"""The virtual lab: noise generators, the virtual IMU and the simulated rig.

:func:`simulate` is the one-call entry point for tests and demos: it runs a sequence on the
simulated rig with a unit drawn from a grade and returns the session and the unit's truth.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path


def simulate(sequence, unit, seed: int, out_dir: str | Path | None = None, rig=None, site=None,
             procedure: str | None = None, progress=None):
    """Record ``sequence`` on the simulated rig; returns ``(Session, UnitTruth)``.

    ``unit``: a grade name or fixture path, a ``SensorSpec`` or a ``UnitTruth`` (drawn from the
    spec with ``seed`` when not already a truth). ``rig``: a ``RigConfig``, a rig-config name or
    path, or None for ``fixtures/rigs/sim.yaml``. ``site``: a ``workbench.session.Site`` that
    replaces the rig's site. ``out_dir``: a folder for the session (with ``truth.json``), or None
    to keep it in memory. The same ``seed`` gives the same samples.
    """
    from workbench.calset import Unit
    from workbench.grades import SensorSpec, UnitTruth, draw_unit, load_spec
    from workbench.rigconfig import RigConfig, load_rig_config
    from workbench.runner import record, start
    from workbench.sim.rig import SimRig

    if isinstance(unit, UnitTruth):
        truth = unit
    else:
        spec = unit if isinstance(unit, SensorSpec) else load_spec(unit)
        truth = draw_unit(spec, seed)
    cfg = rig if isinstance(rig, RigConfig) else load_rig_config(rig or "sim")
    if site is not None:
        cfg = replace(cfg, site=site)
    sim = SimRig(cfg, truth, seed)
    rec = start(sequence, sim, Unit(truth.serial, truth.model), procedure or sequence.name,
                Path(out_dir) if out_dir is not None else None, extra={"seed": int(seed)})
    if out_dir is not None:
        write_truth(Path(out_dir), truth, cfg, seed)
    return record(rec, sim, progress), truth


def write_truth(out_dir: Path, truth, cfg, seed: int) -> None:
    """Write ``truth.json`` beside a simulated session (read by tests, never by analyses)."""
    import json

    import numpy as np

    from workbench.calset import atomic_write_text

    doc = {"seed": int(seed), "unit": truth.to_dict(), "rig": cfg.name,
           "magnetic_field_ned_ut": np.asarray(cfg.magnetic_field_ned).tolist(),
           "positioning_error_rad": cfg.turntable.positioning_error}
    atomic_write_text(out_dir / "truth.json", json.dumps(doc, indent=1, default=lambda o: np.asarray(o).tolist()))
