"""YAML export: the canonical JSON document rendered as YAML (same keys, same SI values)."""

from __future__ import annotations

import yaml

from workbench.calset import CalibrationSet
from workbench.registry import Export

FORMAT = "yaml"
SUFFIX = ".yaml"
DESCRIPTION = "the canonical document as YAML"


def export(calset: CalibrationSet) -> Export:
    """YAML text of the canonical document; nothing is dropped."""
    return Export(yaml.safe_dump(calset.to_dict(), sort_keys=False, default_flow_style=None, width=120))
