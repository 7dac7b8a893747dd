"""Numbers as JSON (workbench/json_values.py): NaN is null, numpy is Python, shapes kept."""

import json
from pathlib import Path

import numpy as np
import pytest

from workbench.json_values import json_default, json_value


def test_values_of_any_shape_with_nan_as_null():
    assert json_value(1.5) == 1.5 and isinstance(json_value(np.float32(1.5)), float)
    assert json_value(np.nan) is None and json_value(np.inf) is None and json_value(None) is None
    assert json_value([1.0, np.nan]) == [1.0, None]
    assert json_value(np.array([[1, 2], [np.nan, 4]])) == [[1.0, 2.0], [None, 4.0]]
    assert json.loads(json.dumps(json_value(np.full((2, 3, 1), np.nan)))) == [[[None]] * 3] * 2


def test_default_for_numpy_and_paths():
    doc = {"a": np.arange(3), "b": np.float64(2.5), "c": np.int64(4), "p": Path("/x/y")}
    assert json.loads(json.dumps(doc, default=json_default)) == {"a": [0, 1, 2], "b": 2.5, "c": 4, "p": "/x/y"}
    with pytest.raises(TypeError, match="not JSON-serialisable: object"):
        json.dumps({"o": object()}, default=json_default)
