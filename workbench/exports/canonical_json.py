"""Canonical JSON export (``workbench-calibration/1``, the format the store keeps)."""

from __future__ import annotations

from workbench.calset import CalibrationSet
from workbench.registry import Export

FORMAT = "json"
SUFFIX = ".json"
DESCRIPTION = "canonical workbench-calibration/1 JSON"


def export(calset: CalibrationSet) -> Export:
    """The set's canonical JSON text; nothing is dropped."""
    return Export(calset.to_json())
