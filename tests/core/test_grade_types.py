"""Value types of a grade (workbench.grade_types)."""

import numpy as np
import pytest

from workbench.grade_types import SpecError, _vec3


def test_vec3_broadcasts_one_value_to_three_axes_and_freezes_it():
    v = _vec3(2.0, "gyro.bias")
    assert v.tolist() == [2.0, 2.0, 2.0] and not v.flags.writeable
    assert _vec3([1, 2, 3], "x").tolist() == [1.0, 2.0, 3.0]
    with pytest.raises(SpecError, match="gyro.bias: NaN or infinite value"):
        _vec3([1.0, np.nan, 0.0], "gyro.bias")
