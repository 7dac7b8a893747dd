"""C header export: compiled with the system C compiler, its compensation equals TriadModel.compensate."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

from tests.exports._thermal_sets import RANGES, expressible_set, true_inputs
from workbench.calset import CalibrationSet, TriadCalibration
from workbench.exports import c_header
from workbench.model import ThermalModel, TriadModel


def full_set() -> CalibrationSet:
    """The expressible set plus what firmware formats drop: misalignment, nonlinearity, G, scale polys."""
    cal = expressible_set()
    g = cal.model("gyro")
    gyro = TriadModel(bias=g.bias, scale_misalignment=[[1e-3, 2e-4, -1e-4], [3e-4, -1e-3, 2e-4], [1e-4, -2e-4, 5e-4]],
                      nonlinearity=[1e-4, -2e-4, 5e-5], g_sensitivity=np.full((3, 3), 1e-5),
                      thermal=ThermalModel(25.0, np.column_stack([g.thermal.bias_poly, np.full((3, 2), 1e-11)]),
                                           [[0, 5e-5, 1e-6], [0, -4e-5, 2e-6], [0, 3e-5, -1e-6]]))
    triads = dict(cal.triads)
    triads["gyro"] = TriadCalibration(gyro, thermal_range_c=(-40.0, 85.0))
    return CalibrationSet(cal.unit, triads)


def test_a_model_holding_a_comment_end_stays_inside_the_comment():
    """The model is free text (one line): '*/' in it must not end the header's comment and start code."""
    from dataclasses import replace

    from workbench.values import Unit

    cal = expressible_set()
    cal = replace(cal, unit=Unit(cal.unit.serial, "evil */ #define WB_ACCEL_BIAS_X 99.0 /*"))
    text = c_header.export(cal).text
    first = text.splitlines()[0]
    assert first.startswith("/*") and first.endswith("*/") and first.count("*/") == 1
    assert "#define WB_ACCEL_BIAS_X 99.0" not in text.replace(first, "")


def _c(values) -> str:
    return ", ".join(repr(float(v)) for v in values)


@pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")
def test_compiled_compensation_equals_the_python_model(tmp_path):
    cal = full_set()
    exp = c_header.export(cal)
    assert exp.dropped == []
    (tmp_path / "cal.h").write_text(exp.text)
    temps = np.linspace(-40, 85, 20)
    cases, expected = [], []
    f = np.array([0.1, -0.2, -9.8])
    for triad in ("gyro", "accel", "mag"):
        model = cal.model(triad)
        x = true_inputs(triad, temps.size, 7)
        kw = {"specific_force": np.tile(f, (temps.size, 1))} if triad == "gyro" else {}
        raw = model.apply(x, temperature_c=temps, **kw)
        expected.append(model.compensate(raw, temperature_c=temps, **kw))
        fa = "f" if triad == "gyro" else "NULL"
        for r, t in zip(raw, temps):
            cases.append(f'{{ double r[3] = {{{_c(r)}}}, o[3]; wb_{triad}_compensate(r, {float(t)!r}, {fa}, o); '
                         'printf("%.17g %.17g %.17g\\n", o[0], o[1], o[2]); }')
    src = ("#include <stdio.h>\n#include \"cal.h\"\nint main(void) {\n"
           f"const double f[3] = {{{_c(f)}}};\n" + "\n".join(cases) + "\nreturn 0; }\n")
    (tmp_path / "main.c").write_text(src)
    subprocess.run(["gcc", "-std=c99", "-Wall", "-Werror", "-o", str(tmp_path / "a.out"), str(tmp_path / "main.c"),
                    "-lm"], check=True, cwd=tmp_path)
    out = np.loadtxt(subprocess.run([str(tmp_path / "a.out")], check=True, capture_output=True, text=True).stdout
                     .splitlines())
    for k, triad in enumerate(("gyro", "accel", "mag")):
        got = out[k * temps.size:(k + 1) * temps.size]
        # double precision on both sides: agreement to 1e-12 of the full scale
        assert np.abs(got - expected[k]).max() < 1e-12 * RANGES[triad], triad
