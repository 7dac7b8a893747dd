"""Value types shared by every layer (no behaviour, no imports of the workbench).

:class:`Unit`: the device under test (serial and model); :data:`GYRO`, :data:`ACCEL`, :data:`MAG`: the
sample columns of each triad (body axes x, y, z), as :mod:`workbench.session` records them.
"""

from __future__ import annotations

from dataclasses import dataclass

GYRO = ["gx", "gy", "gz"]  # rad/s
ACCEL = ["ax", "ay", "az"]  # m/s^2
MAG = ["mx", "my", "mz"]  # uT


@dataclass(frozen=True)
class Unit:
    """The device under test."""

    serial: str
    model: str = ""
