"""Multi-position static tumble: accelerometer bias, M, nonlinearity; gyro bias and g-sensitivity.

Sequence: static holds with gravity along chosen body directions (``positions``):
6 = the six axis-up/down faces; 12 = the twelve cube edges (gravity at 45° between two
axes, 0.71 g on each); 18 = faces + edges; 24 = faces + edges + the faces again with the
table turned by 180° (the Earth rate's horizontal part reverses). ``dwell_s`` per position,
``table_angle_deg`` for the first pass.

Analysis (``workbench analyze multiposition SESSION_DIR``):
:func:`workbench.analysis.turntable.fit_accel` and :func:`fit_gyro_static` on all static
steps. Options: ``nonlinearity`` (auto | fit | none), ``earth_rate`` (auto | model | ignore),
``position_sigma_deg`` (1-sigma tilt of each position: the fixture's repeatability, default
0.01°; ``"auto"`` for hand-made positions), ``settle_s``, ``accel_bias_instability_mg`` /
``gyro_bias_instability_deg_h`` (the unit's bias instability B from its Allan result, scalar or
3 axes: a floor for the bias wander that short dwells cannot show; default none, and a
warning says when the dwells could hide one larger than the bias sigma).

References: thesis sec. 1.3 (shared/seeds/000_...).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from workbench import units
from workbench.analysis.turntable import TriadFit, fit_accel, fit_gyro_static
from workbench.calset import CalibrationSet
from workbench.errors import ProcedureError
from workbench.options import Option, check_options, defaults
from workbench.procedure import ProcedureResult
from workbench.sequence import Hold, Sequence, mount_matrix
from workbench.session import Session

NAME = "multiposition"
TITLE = "Multi-position static tumble (accelerometer bias/M/nonlinearity, gyro bias/g-sensitivity)"
TRIADS = ("accel", "gyro")
CAMPAIGN_ORDER = 20
POSITION_SETS = (6, 12, 18, 24)
OPTIONS = (
    Option("positions", "sequence", "int", 6, "position set: 6 faces, 12 edges, 18 both, 24 with the faces again "
           "at table 180°", choices=POSITION_SETS),
    Option("dwell_s", "sequence", "float", 60.0, "hold per position", unit="s", gt=0),
    Option("table_angle_deg", "sequence", "float", 0.0, "table angle of the first pass", unit="deg"),
    Option("nonlinearity", "analysis", "str", "auto", "accelerometer nonlinearity term",
           choices=("auto", "fit", "none")),
    Option("earth_rate", "analysis", "str", "auto", "Earth rate in the gyro static fit",
           choices=("auto", "model", "ignore")),
    Option("position_sigma_deg", "analysis", "float", 0.01, "1-sigma tilt of each position (fixture "
           "repeatability; 'auto' estimates it for hand-made positions)", unit="deg", ge=0, words=("auto",)),
    Option("settle_s", "analysis", "float", 1.0, "dropped at the start of each step", unit="s", ge=0),
    Option("accel_bias_instability_mg", "analysis", "magnitude", None, "accelerometer bias instability B "
           "(Allan), a floor for the bias sigma", unit="mg"),
    Option("gyro_bias_instability_deg_h", "analysis", "magnitude", None, "gyro bias instability B (Allan), "
           "a floor for the bias sigma", unit="deg/h"),
)
DEFAULTS = defaults(OPTIONS)


def _edge_mount(up_body: np.ndarray) -> np.ndarray:
    """A mount (body->table-top) putting the body direction ``up_body`` along the table's up (-z)."""
    rot, _ = Rotation.align_vectors([[0.0, 0.0, -1.0]], [up_body / np.linalg.norm(up_body)])
    return rot.as_matrix()


def positions(n: int) -> list[tuple[object, str, float]]:
    """The (mount, label, extra table angle rad) of an ``n``-position set (6, 12, 18 or 24)."""
    if n not in POSITION_SETS:
        raise ProcedureError(f"{NAME}: positions={n} (expected one of {', '.join(map(str, POSITION_SETS))})")
    faces = [(name, name, 0.0) for name in ("x-up", "x-down", "y-up", "y-down", "z-up", "z-down")]
    edges = []
    for i, j in ((0, 1), (0, 2), (1, 2)):
        for si in (1, -1):
            for sj in (1, -1):
                up = np.zeros(3)
                up[i], up[j] = si, sj
                label = f"{'+' if si > 0 else '-'}{'xyz'[i]}{'+' if sj > 0 else '-'}{'xyz'[j]} up"
                edges.append((_edge_mount(up).tolist(), label, 0.0))
    if n == 6:
        return faces
    if n == 12:
        return edges
    if n == 18:
        return faces + edges
    return faces + edges + [(m, f"{lbl} table 180°", np.pi) for m, lbl, _ in faces]


def sequence(spec, **opts) -> Sequence:
    """Static holds at the chosen position set (see the module docstring)."""
    o = check_options(NAME, OPTIONS, opts, "sequence")
    dwell = o["dwell_s"]
    base = o.si("table_angle_deg")
    steps = [Hold(m, base + extra, dwell, label) for m, label, extra in positions(o["positions"])]
    for s in steps:
        mount_matrix(s.mount)  # validate
    return Sequence(NAME, steps, options=dict(o))


def position_sigma(value) -> float | str:
    """The ``position_sigma_deg`` option in rad (or ``"auto"``)."""
    return "auto" if value == "auto" else float(np.radians(float(value)))


def analyze(session: Session, **opts) -> ProcedureResult:
    """Accelerometer and gyro static fits of all static steps (see the module docstring)."""
    o = check_options(NAME, OPTIONS, opts, "analysis")
    acc = fit_accel(session, None, o["nonlinearity"], settle_s=o["settle_s"],
                    position_sigma=o.si("position_sigma_deg"),
                    bias_instability=o.si("accel_bias_instability_mg"))
    gyr = fit_gyro_static(session, None, o["earth_rate"], settle_s=o["settle_s"],
                          bias_instability=o.si("gyro_bias_instability_deg_h"))
    calset = CalibrationSet(unit=session.unit, triads={"accel": acc.to_calibration(), "gyro": gyr.to_calibration()},
                            notes={NAME: {"accel": dict(acc.notes), "gyro": dict(gyr.notes)}})
    return ProcedureResult(NAME, result=result_dict({"accel": acc, "gyro": gyr}), calibration=calset,
                           payload={"accel": acc, "gyro": gyr},
                           summary=fit_summary(acc) + fit_summary(gyr), warnings=[*acc.warnings, *gyr.warnings])


def result_dict(fits: dict[str, TriadFit], full_scale: float | None = None) -> dict:
    """``result.json`` content: each fit's estimates and sigmas (SI) and its residual table."""
    out = {}
    for name, fit in fits.items():
        d = fit.to_dict()
        d["residuals"] = fit.residuals.to_dict(orient="records")
        out[name] = d
    if full_scale is not None:
        out["full_scale_rad_s"] = full_scale
    return out


def fit_summary(fit: TriadFit, full_scale: float | None = None) -> list[str]:
    """Lines for people in lab units: bias (mg or °/h), scale factor (ppm), misalignment (mrad),
    nonlinearity and residuals before/after (mg, or °/h and % of full scale for a rate fit)."""
    acc = fit.triad == "accel"
    b_unit = "mg" if acc else "deg/h"

    def pm(v, s, unit, digits=4):
        return f"{units.fmt(v, unit, digits)} ± {units.fmt(s, unit, 2)}"

    t = fit.triad
    lines = []
    if np.isfinite(fit.bias_sigma).any():
        lines.append(f"{t} bias: " + ", ".join(f"{a} {pm(v, s, b_unit)}"
                                               for a, v, s in zip("xyz", fit.bias, fit.bias_sigma)))
    d, ds = np.diag(fit.scale_misalignment), np.diag(fit.scale_misalignment_sigma)
    if np.isfinite(ds).any():
        lines.append(f"{t} scale factor: " + ", ".join(f"{a} {pm(v, s, 'ppm', 5)}" for a, v, s in zip("xyz", d, ds)))
        off = ~np.eye(3, dtype=bool)
        worst = np.abs(fit.scale_misalignment[off]).max()
        lines.append(f"{t} misalignment: largest |M_ij| {units.fmt(worst, 'mrad', 3)}, "
                     f"largest sigma {units.fmt(np.nanmax(fit.scale_misalignment_sigma[off]), 'mrad', 2)}")
    if np.isfinite(fit.nonlinearity_sigma).any():
        lines.append(f"{t} nonlinearity (1/SI): " + ", ".join(
            f"{a} {v:.3g} ± {s:.2g}" for a, v, s in zip("xyz", fit.nonlinearity, fit.nonlinearity_sigma)
            if np.isfinite(s)))
    if np.isfinite(fit.asymmetry_sigma).any():
        lines.append(f"{t} scale-factor asymmetry (SF+ - SF-)/2: " + ", ".join(
            f"{a} {pm(v, s, 'ppm', 3)}" for a, v, s in zip("xyz", fit.asymmetry, fit.asymmetry_sigma)))
    if fit.g_sensitivity is not None and np.isfinite(fit.g_sensitivity_sigma).any():
        gs = units.factor("deg/h") / units.factor("g")
        lines.append(f"{t} g-sensitivity: largest |G_ij| {np.abs(fit.g_sensitivity).max() / gs:.3g} °/h/g "
                     f"(largest sigma {np.nanmax(fit.g_sensitivity_sigma) / gs:.2g} °/h/g)")
    r = fit.residuals[fit.residuals["used"]] if len(fit.residuals) else fit.residuals
    if len(r):
        before = np.abs(r[["before_x", "before_y", "before_z"]].to_numpy()).max()
        after = np.abs(r[["after_x", "after_y", "after_z"]].to_numpy()).max()
        res_unit = "mg" if acc else "deg/s"
        line = (f"{t} max residual per step: before {units.fmt(before, res_unit, 3)}, "
                f"after {units.fmt(after, res_unit, 3)}")
        if full_scale:
            line += f" ({after / full_scale * 100:.3g} % of full scale {units.fmt(full_scale, 'deg/s', 4)})"
        lines.append(line)
        if acc:
            lines.append(f"{t} max | |a| - g | per step: before {units.fmt(np.abs(r['before_norm']).max(), 'mg', 3)}, "
                         f"after {units.fmt(np.abs(r['after_norm']).max(), 'mg', 3)}")
    for k, v in fit.notes.items():
        if k == "earth_rate":
            lines.append(f"{t} Earth rate: {v}")
    return lines


def figures(result: ProcedureResult) -> dict:
    """Per-position residuals before/after compensation, per triad."""
    from workbench.plots.turntable import plot_residuals

    return {f"{name}_residuals": plot_residuals(fit) for name, fit in result.payload.items()}
