"""Summary lines and the result protocol of a turntable fit (TriadFit), on fits with known values.

The values are exact lab-unit numbers converted to SI here, so each line must show them back
exactly (formatting only, no tolerance)."""

import numpy as np
import pandas as pd
import pytest

from workbench.analysis.turntable_fit import TriadFit
from workbench.calset import CalibrationSet, TriadCalibration, Unit
from workbench.result import AnalysisResult, CoefficientResult
from workbench.units import factor

NAN3, NAN33 = np.full(3, np.nan), np.full((3, 3), np.nan)


def _fit(triad: str, bias_lab: float, bias_unit: str, observed_m: bool = True, **kw) -> TriadFit:
    m = np.diag([100e-6, -200e-6, 300e-6])
    m[0, 1] = 0.5e-3  # 0.5 mrad, the largest off-diagonal
    return TriadFit(triad, np.array([bias_lab, -bias_lab, 2 * bias_lab]) * factor(bias_unit), m, np.zeros(3), None,
                    np.full(3, 0.1 * bias_lab * factor(bias_unit)),
                    np.full((3, 3), 10e-6) if observed_m else NAN33, NAN3, None, **kw)


def test_gyro_lines_in_lab_units():
    lines = _fit("gyro", 1.5, "deg/h").summary()
    assert lines[0] == "gyro bias: x 1.5 ± 0.15 °/h, y -1.5 ± 0.15 °/h, z 3 ± 0.15 °/h"  # one unit per figure
    assert lines[1] == "gyro scale factor: x 100 ± 10 ppm, y -200 ± 10 ppm, z 300 ± 10 ppm"
    assert lines[2] == "gyro misalignment: largest |M_ij| 0.5 mrad, largest sigma 0.01 mrad"
    assert not any("nonlinearity" in line for line in lines)  # not observed: not listed


def test_accel_bias_in_mg_and_unobserved_scale_left_out():
    lines = _fit("accel", 2.0, "mg", observed_m=False).summary()
    assert lines == ["accel bias: x 2 ± 0.2 mg, y -2 ± 0.2 mg, z 4 ± 0.2 mg"]


@pytest.mark.parametrize("triad,unit,label", [("gyro", "ppm/(deg/s)", "ppm/(°/s)"), ("accel", "ug/g^2", "µg/g²")])
def test_nonlinearity_in_lab_units_not_si(triad, unit, label):
    fit = _fit(triad, 1.0, "deg/h" if triad == "gyro" else "mg")
    fit = TriadFit(fit.triad, fit.bias, fit.scale_misalignment, np.array([0.5, 0.0, -2.0]) * factor(unit), None,
                   fit.bias_sigma, fit.scale_misalignment_sigma, np.array([0.05, 0.05, np.nan]) * factor(unit), None)
    (line,) = [line for line in fit.summary() if "nonlinearity" in line]
    assert line == f"{triad} nonlinearity: x 0.5 ± 0.05 {label}, y 0 ± 0.05 {label}"  # z not observed: left out


def test_residual_line_and_percent_of_full_scale():
    fs = np.radians(100.0)  # rad/s
    res = pd.DataFrame({"used": [True, False], **{f"before_{a}": [np.radians(0.5), 9.0] for a in "xyz"},
                        **{f"after_{a}": [np.radians(0.01), 9.0] for a in "xyz"}})
    lines = _fit("gyro", 1.0, "deg/h", residuals=res).summary(fs)
    # the unused step (9 rad/s) is left out; 0.01 °/s of 100 °/s full scale is 0.01 %
    assert lines[-1] == ("gyro max residual per step: before 0.5 °/s, after 0.01 °/s "
                         "(0.01 % of full scale 100 °/s)")


def test_earth_rate_note_is_a_line():
    lines = _fit("gyro", 1.0, "deg/h", notes={"earth_rate": "not modelled"}).summary()
    assert lines[-1] == "gyro Earth rate: not modelled"


def test_protocol_and_calibration_of_a_unit():
    fit = _fit("gyro", 1.0, "deg/h")
    assert isinstance(fit, AnalysisResult) and isinstance(fit, CoefficientResult)
    assert isinstance(fit.to_calibration(), TriadCalibration)  # without a unit: the triad alone
    cal = fit.to_calibration(Unit("SN1", "m"))
    assert isinstance(cal, CalibrationSet) and set(cal.triads) == {"gyro"} and cal.unit.serial == "SN1"
    np.testing.assert_array_equal(cal.triads["gyro"].model.bias, fit.bias)
    assert cal.triads["gyro"].sigma_of("bias") == pytest.approx(fit.bias_sigma)
