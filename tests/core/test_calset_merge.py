"""Merging partial sets (workbench/calset_merge.py): thermal blocks, field norm, noise terms, ties, model name.

The element-wise choice by sigma and provenance are in tests/core/test_calset.py; here the rest of
the rules, each on sets built by hand so the expected merge is known exactly."""

import numpy as np
import pytest

from workbench.calset import CalibrationSet, TriadCalibration, Unit
from workbench.calset_merge import merge
from workbench.errors import CalibrationFormatError
from workbench.model import ThermalModel, TriadModel


def _set(triads: dict, model: str = "", **kw) -> CalibrationSet:
    return CalibrationSet(Unit("U1", model), triads, **kw)


def test_tie_and_unobserved_take_the_later_set():
    a = _set({"gyro": TriadCalibration(TriadModel(bias=[1, 1, 1]), {"bias": np.array([1e-3, np.nan, 1e-3])})})
    b = _set({"gyro": TriadCalibration(TriadModel(bias=[2, 2, 2]), {"bias": np.array([1e-3, np.nan, 2e-3])})})
    m = merge(a, b)
    # x: equal sigma -> later (b); y: neither observed -> later (b); z: a better determined -> a
    np.testing.assert_array_equal(m.model("gyro").bias, [2, 2, 1])
    np.testing.assert_array_equal(m.triads["gyro"].sigma_of("bias"), [1e-3, np.nan, 1e-3])


def test_thermal_block_and_field_norm_from_the_latest_set_that_has_them():
    th = ThermalModel(25.0, np.ones((3, 2)) * 1e-4, np.zeros((3, 1)))
    hot = TriadCalibration(TriadModel(bias=[0, 0, 0], thermal=th), {"bias": np.full(3, 1e-4),
                           "thermal.bias_poly": np.full((3, 2), 1e-6)}, thermal_range_c=(5.0, 45.0))
    plain = TriadCalibration(TriadModel(bias=[0, 0, 0]), {"bias": np.full(3, 1e-4)})
    m = merge(_set({"accel": hot}), _set({"accel": plain}))
    assert m.model("accel").thermal is th and m.triads["accel"].thermal_range_c == (5.0, 45.0)
    assert "thermal.bias_poly" in m.triads["accel"].sigma
    mag_a = TriadCalibration(TriadModel(bias=[0, 0, 0]), {}, field_norm_ut=48.0, field_norm_ut_sigma=0.2)
    mag_b = TriadCalibration(TriadModel(bias=[0, 0, 0]), {}, field_norm_ut=None)
    mb = merge(_set({"mag": mag_a}), _set({"mag": mag_b})).triads["mag"]
    assert (mb.field_norm_ut, mb.field_norm_ut_sigma) == (48.0, 0.2)


def test_noise_terms_observed_values_win_with_their_interval():
    gyro = TriadCalibration(TriadModel(bias=[0, 0, 0]), {})
    a = _set({"gyro": gyro}, noise={"gyro": {"arw": [1e-4, 1e-4, 1e-4], "arw_ci95": [[0.9e-4, 1.1e-4]] * 3}})
    b = _set({"gyro": gyro}, noise={"gyro": {"arw": [None, None, None]}})
    c = _set({"gyro": gyro}, noise={"gyro": {"arw": [2e-4, 2e-4, 2e-4], "arw_ci95": [[1.9e-4, 2.1e-4]] * 3}})
    assert merge(a, b).noise["gyro"]["arw"] == [1e-4] * 3  # an all-unobserved term does not replace
    m = merge(a, c).noise["gyro"]
    assert m["arw"] == [2e-4] * 3 and m["arw_ci95"] == [[1.9e-4, 2.1e-4]] * 3


def test_model_name_from_the_latest_set_naming_it_and_no_sets_refused():
    gyro = TriadCalibration(TriadModel(bias=[0, 0, 0]), {})
    assert merge(_set({"gyro": gyro}, "m1"), _set({"gyro": gyro}, "")).unit.model == "m1"
    with pytest.raises(CalibrationFormatError, match="no calibration sets"):
        merge()
