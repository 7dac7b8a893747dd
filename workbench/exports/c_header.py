"""C header: the full error model of every triad, for embedded code, with its compensation function.

For each triad ``<t>`` (gyro, accel, mag) the header defines, in SI (rad/s, m/s^2, µT, °C):
``WB_<T>_BIAS[3]``, ``WB_<T>_GAIN[3][3]`` (``I + M``), ``WB_<T>_NONLIN[3]``, ``WB_<T>_GSENS[3][3]``
(zero when absent), ``WB_<T>_T_REF_C``, ``WB_<T>_T_MIN_C``/``T_MAX_C`` (the valid range; NaN when
unknown), ``WB_<T>_BIAS_POLY[3][K]`` and ``WB_<T>_SCALE_POLY[3][K]`` (column k multiplies
``(T - t_ref)^k``), and ``static inline void wb_<t>_compensate(const double raw[3], double temp_c,
const double f[3], double out[3])``: the exact inverse of ``workbench/model.py``::

    r = raw - b(T) - G f;  u = 2 r / (1 + sqrt(1 + 4 n r));  out = inv(I + M(T)) u

``f`` (compensated specific force, m/s^2) may be NULL. Nothing of the model is dropped; the
temperature is not clamped (callers may clamp to the valid range).
"""

from __future__ import annotations

import re

import numpy as np

from workbench.calset import CalibrationSet
from workbench.registry import Export

FORMAT = "c-header"
SUFFIX = ".h"
DESCRIPTION = "C header with the full model (bias, I+M, nonlinearity, G, thermal polynomials) and compensation"

_SOLVE = """static inline void wb_solve3(const double a[3][3], const double r[3], double x[3])
{
    /* x = inv(a) r by the adjugate (a is close to identity) */
    const double c00 = a[1][1] * a[2][2] - a[1][2] * a[2][1];
    const double c01 = a[1][2] * a[2][0] - a[1][0] * a[2][2];
    const double c02 = a[1][0] * a[2][1] - a[1][1] * a[2][0];
    const double det = a[0][0] * c00 + a[0][1] * c01 + a[0][2] * c02;
    const double inv[3][3] = {
        {c00, a[0][2] * a[2][1] - a[0][1] * a[2][2], a[0][1] * a[1][2] - a[0][2] * a[1][1]},
        {c01, a[0][0] * a[2][2] - a[0][2] * a[2][0], a[0][2] * a[1][0] - a[0][0] * a[1][2]},
        {c02, a[0][1] * a[2][0] - a[0][0] * a[2][1], a[0][0] * a[1][1] - a[0][1] * a[1][0]}};
    for (int i = 0; i < 3; ++i)
        x[i] = (inv[i][0] * r[0] + inv[i][1] * r[1] + inv[i][2] * r[2]) / det;
}

static inline double wb_poly(const double *c, int n, double dt)
{
    double v = 0.0;
    for (int k = n - 1; k >= 0; --k)
        v = v * dt + c[k];
    return v;
}
"""

_FUNC = """static inline void wb_{t}_compensate(const double raw[3], double temp_c, const double f[3], double out[3])
{{
    const double dt = temp_c - WB_{T}_T_REF_C;
    double gain[3][3], r[3];
    for (int i = 0; i < 3; ++i) {{
        for (int j = 0; j < 3; ++j)
            gain[i][j] = WB_{T}_GAIN[i][j];
        gain[i][i] += wb_poly(WB_{T}_SCALE_POLY[i], WB_{T}_SCALE_K, dt);
        r[i] = raw[i] - WB_{T}_BIAS[i] - wb_poly(WB_{T}_BIAS_POLY[i], WB_{T}_BIAS_K, dt);
        if (f)
            r[i] -= WB_{T}_GSENS[i][0] * f[0] + WB_{T}_GSENS[i][1] * f[1] + WB_{T}_GSENS[i][2] * f[2];
        if (WB_{T}_NONLIN[i] != 0.0)
            r[i] = 2.0 * r[i] / (1.0 + sqrt(1.0 + 4.0 * WB_{T}_NONLIN[i] * r[i]));
    }}
    wb_solve3((const double(*)[3])gain, r, out);
}}
"""


def _num(v: float) -> str:
    return "NAN" if not np.isfinite(v) else repr(float(v))


def _array(name: str, a: np.ndarray) -> str:
    a = np.asarray(a, float)
    if a.ndim == 1:
        return f"static const double {name}[{a.size}] = {{{', '.join(_num(v) for v in a)}}};"
    rows = ", ".join("{" + ", ".join(_num(v) for v in row) + "}" for row in a)
    return f"static const double {name}[{a.shape[0]}][{a.shape[1]}] = {{{rows}}};"


def _triad(name: str, calset: CalibrationSet) -> list[str]:
    tc = calset.triads[name]
    m = tc.model
    T = name.upper()
    th = m.thermal
    bias_poly = th.bias_poly if th is not None and th.bias_poly.shape[1] else np.zeros((3, 1))
    scale_poly = th.scale_poly if th is not None and th.scale_poly.shape[1] else np.zeros((3, 1))
    t_min, t_max = tc.thermal_range_c if tc.thermal_range_c is not None else (np.nan, np.nan)
    lines = [f"/* {name}: measured = (I + M(T)) x + n u^2 + b(T) + G f, SI units */",
             _array(f"WB_{T}_BIAS", m.bias), _array(f"WB_{T}_GAIN", m.gain), _array(f"WB_{T}_NONLIN", m.nonlinearity),
             _array(f"WB_{T}_GSENS", m.g_sensitivity if m.g_sensitivity is not None else np.zeros((3, 3))),
             f"static const double WB_{T}_T_REF_C = {_num(th.t_ref_c if th is not None else 0.0)};",
             f"static const double WB_{T}_T_MIN_C = {_num(t_min)};",
             f"static const double WB_{T}_T_MAX_C = {_num(t_max)};",
             f"enum {{ WB_{T}_BIAS_K = {bias_poly.shape[1]}, WB_{T}_SCALE_K = {scale_poly.shape[1]} }};",
             _array(f"WB_{T}_BIAS_POLY", bias_poly), _array(f"WB_{T}_SCALE_POLY", scale_poly)]
    if name == "mag" and tc.field_norm_ut is not None:
        lines.append(f"static const double WB_MAG_FIELD_NORM_UT = {_num(tc.field_norm_ut)};")
    return lines + ["", _FUNC.format(t=name, T=T)]


def export(calset: CalibrationSet) -> Export:
    """The header text; nothing is dropped (the whole model is written)."""
    guard = "WB_CAL_" + re.sub(r"[^A-Za-z0-9]", "_", calset.unit.serial or "UNIT").upper() + "_H"
    about = f"Calibration set {calset.id} of unit {calset.unit.serial} {calset.unit.model}".rstrip()
    out = [f"/* {about.replace('*/', '* /')} */",  # a model is free text: it cannot close the comment
           f"/* generated by the calibration workbench ({calset.created}) */",
           f"#ifndef {guard}", f"#define {guard}", "", "#include <math.h>", "#include <stddef.h>", "", _SOLVE]
    for name in ("gyro", "accel", "mag"):
        if name in calset.triads:
            out += _triad(name, calset)
    out += [f"#endif /* {guard} */", ""]
    return Export("\n".join(out), [])
