"""The virtual lab: noise generators, the virtual IMU, the simulated rig and the loopback lab.

Modules: :mod:`~workbench.sim.noise`, :mod:`~workbench.sim.sensor`, :mod:`~workbench.sim.rig`
(``SimRig``), :mod:`~workbench.sim.hil` (the hardware-in-the-loop loopback instruments).
:func:`write_truth` writes a simulated unit's truth beside its session. Recording a sequence
on the simulated rig is orchestration, above this package: :func:`workbench.jobs.simulate`.
"""

from __future__ import annotations

from pathlib import Path


def write_truth(out_dir: Path, truth, cfg, seed: int) -> None:
    """Write ``truth.json`` beside a simulated session (read by tests, never by analyses)."""
    import json

    import numpy as np

    from workbench.files import atomic_write_text

    doc = {"seed": int(seed), "unit": truth.to_dict(), "rig": cfg.name,
           "magnetic_field_ned_ut": np.asarray(cfg.magnetic_field_ned).tolist(),
           "positioning_error_rad": cfg.turntable.positioning_error}
    atomic_write_text(out_dir / "truth.json", json.dumps(doc, indent=1, default=lambda o: np.asarray(o).tolist()))
