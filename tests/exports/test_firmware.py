"""What the autopilot models keep (workbench/exports/_firmware.py), against closed forms."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from workbench.calset import CalibrationSet, TriadCalibration, Unit
from workbench.exports import _firmware as fw
from workbench.model import ThermalModel, TriadModel
from workbench.units import factor


def _set(triads: dict) -> CalibrationSet:
    return CalibrationSet(Unit("SN", "m"), triads)


def test_cubic_bias_kept_exactly_and_higher_order_replaced_by_its_least_squares_cubic():
    poly3 = np.array([[0.0, 1e-5, 2e-7, -3e-9]] * 3)
    th = ThermalModel(25.0, poly3, np.zeros((3, 0)))
    tc = TriadCalibration(TriadModel(bias=[0, 0, 0], thermal=th), {}, thermal_range_c=(-10.0, 60.0))
    dropped: list[str] = []
    coeffs, t_ref, lo, hi = fw.bias_cubic(_set({"accel": tc}), "accel", dropped)
    np.testing.assert_array_equal(coeffs, poly3)
    assert (t_ref, lo, hi) == (25.0, -10.0, 60.0) and dropped == []
    # a quartic: its best cubic over [lo, hi] leaves the Chebyshev equioscillation error
    # a4 (h/2)^4 / 8 (h the range width), attained at the ends of the range
    a4 = 1e-10
    poly4 = np.array([[0.0, 1e-5, 0.0, 0.0, a4]] * 3)
    tc4 = TriadCalibration(TriadModel(bias=[0, 0, 0], thermal=ThermalModel(25.0, poly4, np.zeros((3, 0)))), {},
                           thermal_range_c=(-10.0, 60.0))
    dropped = []
    cubic, *_ = fw.bias_cubic(_set({"accel": tc4}), "accel", dropped)
    t = np.linspace(-10.0, 60.0, 2001) - 25.0
    err = np.abs((t[:, None] ** np.arange(4)) @ cubic[0] - (t[:, None] ** np.arange(5)) @ poly4[0]).max()
    minimax = a4 * (70.0 / 2) ** 4 / 8
    assert minimax <= err < 1.1 * minimax  # least squares on Chebyshev nodes is near-minimax
    assert len(dropped) == 1 and "order 4 > 3 replaced by its least-squares cubic" in dropped[0]
    assert "mg" in dropped[0]


def test_no_range_collapses_to_t_ref_and_says_so():
    th = ThermalModel(20.0, np.array([[0.0, 1e-5]] * 3), np.zeros((3, 0)))
    dropped: list[str] = []
    _, t_ref, lo, hi = fw.bias_cubic(_set({"gyro": TriadCalibration(TriadModel(bias=[0, 0, 0], thermal=th), {})}),
                                     "gyro", dropped)
    assert lo == hi == t_ref == 20.0 and "no valid range" in dropped[0]


def test_inertial_dropped_names_each_lost_term_in_lab_units():
    m = np.diag([100e-6, 0.0, 0.0])
    m[1, 0] = 0.25e-3
    tc = TriadCalibration(TriadModel(bias=[0, 0, 0], scale_misalignment=m, nonlinearity=[1e-6, 0, 0]), {})
    out = fw.inertial_dropped(_set({"gyro": tc}), "gyro", scale_supported=False, target="PX4")
    assert out[0] == "gyro: misalignment (off-diagonal M, max 0.25 mrad): PX4 has no cross-axis terms"
    assert out[1] == "gyro: scale factor (diag M, max 100 ppm): PX4 has no gyro scale parameter"
    assert out[2] == "gyro: quadratic nonlinearity: PX4 has no such term"
    assert len(fw.inertial_dropped(_set({"gyro": tc}), "gyro", scale_supported=True, target="PX4")) == 2


def test_soft_iron_symmetric_factor_and_reported_rotation():
    s = np.array([[1.02, 0.01, 0.0], [0.01, 0.98, 0.005], [0.0, 0.005, 1.01]])
    rot = Rotation.from_rotvec([0.0, 0.0, np.radians(2.0)]).as_matrix()
    # the model's gain is inv(correction); correction = rot @ s
    gain = np.linalg.inv(rot @ s)
    tc = TriadCalibration(TriadModel(bias=[1.0, -2.0, 3.0], scale_misalignment=gain - np.eye(3)), {})
    dropped: list[str] = []
    hard, sym = fw.soft_iron(_set({"mag": tc}), dropped, "ArduPilot")
    np.testing.assert_allclose(hard, [1.0, -2.0, 3.0])
    np.testing.assert_allclose(sym, s, atol=1e-12)
    assert "rotation part of the soft-iron correction (2°)" in dropped[0]
    assert fw.soft_iron(_set({"gyro": tc}), [], "x") is None
    assert fw.LAB["accel"] == "mg" and factor(fw.LAB["gyro"]) == pytest.approx(factor("deg/h"))


def test_header_names_the_set_and_the_unit():
    cal = _set({})
    assert fw.header(cal, "PX4") == [f"# PX4 parameters from workbench calibration set {cal.id}", "# unit SN m"]
