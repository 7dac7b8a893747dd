"""Numbers as JSON, written once: NaN ("not observed") becomes null, numpy becomes Python.

:func:`json_value` (a float or an array of any shape -> float / nested lists, NaN and inf -> None)
and :func:`json_default` (the ``default=`` of :func:`json.dumps` for numpy arrays and scalars and
paths). Units are the caller's (SI inside the workbench).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np


def json_value(x: Any) -> float | None | list:
    """``x`` (a number, an array of any shape, or None) as JSON: floats in nested lists, NaN / inf -> None."""
    if x is None:
        return None
    arr = np.asarray(x, float)
    if arr.ndim:
        return [json_value(v) for v in arr]
    return float(arr) if np.isfinite(arr) else None


def json_default(obj: Any) -> Any:
    """``json.dumps(..., default=json_default)``: numpy arrays -> lists, numpy scalars -> numbers, paths -> str."""
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON-serialisable: {type(obj).__name__}")
