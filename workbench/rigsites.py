"""Site data the rig configurations hold, for the procedure adapters (analyses get it as arguments).

:func:`declination`: the magnetic declination of a session's site, from the option or the rig
configuration (``fixtures/rigs/*.yaml``) named in the session.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from workbench.errors import AnalysisError
from workbench.session import Session


def declination(session: Session, override_deg: float | None = None) -> float:
    """Magnetic declination (rad, east of true north) of the session's site.

    ``override_deg`` if given; else the rig configuration named in the session
    (``fixtures/rigs/*.yaml`` whose ``name`` matches ``session.rig``); else AnalysisError.
    """
    if override_deg is not None:
        return float(np.radians(override_deg))
    from workbench.rigconfig import RIGS_DIR, load_rig_config

    for path in sorted(Path(RIGS_DIR).glob("*.yaml")):
        cfg = load_rig_config(path)  # the strict schema, as every rig configuration is read
        if session.rig is not None and cfg.name == session.rig:
            north, east = cfg.magnetic_field_ned[:2]
            return float(np.arctan2(east, north))
    raise AnalysisError(f"{session.name}: magnetic declination unknown (rig {session.rig!r} has no configuration): "
                        "pass declination_deg")
