"""Value types shared by every layer (no behaviour, no imports of the workbench).

:class:`Unit`: the device under test (serial and model).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Unit:
    """The device under test."""

    serial: str
    model: str = ""
