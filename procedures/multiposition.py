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

A session of ``free`` steps (the unit set down by hand, no table) is analysed from its still
stretches (stationarity detector): the accelerometer from the gravity norm (no orientation known;
at least 6 stretches) and the gyro bias (:mod:`workbench.analysis.still_fit`).

References: thesis sec. 1.3 (shared/seeds/000_...).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from procedures._triad import result_dict
from workbench.analysis.still_fit import fit_accel_norm, fit_gyro_bias, still_means
from workbench.analysis.turntable import fit_accel, fit_gyro_static
from workbench.calset import CalibrationSet
from workbench.errors import AnalysisError, ProcedureError
from workbench.options import Option, check_options, defaults
from workbench.plausibility import grade_of
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


def _analyze_free(session: Session) -> ProcedureResult:
    """Still stretches of ``free`` steps (by hand): gravity-norm accelerometer fit and gyro bias
    (:mod:`workbench.analysis.still_fit`); an accelerometer the stretches cannot observe is left out."""
    means = still_means(session)
    fits, warnings = {}, []
    try:
        fits["accel"] = fit_accel_norm(means, session.site.gravity)
    except AnalysisError as exc:
        warnings.append(f"accelerometer not calibrated: {exc}")
    gyro_spec = getattr(grade_of(session.unit.model), "gyro", None)  # a grade without g-sensitivity has none
    g_sens = None if gyro_spec is None else (np.zeros(3) if gyro_spec.g_sensitivity is None else gyro_spec.g_sensitivity)
    fits["gyro"] = fit_gyro_bias(means, session.site.latitude, g_sens)
    calset = CalibrationSet(unit=session.unit, triads={k: f.triad_calibration() for k, f in fits.items()},
                            notes={NAME: {k: dict(f.notes) for k, f in fits.items()}})
    head = [f"free steps: {len(means)} still stretch(es), {sum(m.n for m in means) / session.sample_rate_hz:.1f} s "
            "(found by the stationarity detector; no orientation known)"]
    return ProcedureResult(NAME, result={**result_dict(fits), "still_stretches": len(means)}, calibration=calset,
                           payload=fits, summary=head + [line for f in fits.values() for line in f.summary()],
                           warnings=[*warnings, *(w for f in fits.values() for w in f.warnings)])


def analyze(session: Session, **opts) -> ProcedureResult:
    """Accelerometer and gyro static fits of all static steps, or of the still stretches of free steps
    (see the module docstring)."""
    o = check_options(NAME, OPTIONS, opts, "analysis")
    if session.steps_of_kind("free") and not session.steps_of_kind("static"):
        return _analyze_free(session)
    acc = fit_accel(session, None, o["nonlinearity"], settle_s=o["settle_s"],
                    position_sigma=o.si("position_sigma_deg"),
                    bias_instability=o.si("accel_bias_instability_mg"))
    gyr = fit_gyro_static(session, None, o["earth_rate"], settle_s=o["settle_s"],
                          bias_instability=o.si("gyro_bias_instability_deg_h"))
    calset = CalibrationSet(unit=session.unit, triads={"accel": acc.triad_calibration(), "gyro": gyr.triad_calibration()},
                            notes={NAME: {"accel": dict(acc.notes), "gyro": dict(gyr.notes)}})
    return ProcedureResult(NAME, result=result_dict({"accel": acc, "gyro": gyr}), calibration=calset,
                           payload={"accel": acc, "gyro": gyr},
                           summary=acc.summary() + gyr.summary(), warnings=[*acc.warnings, *gyr.warnings])


def figures(result: ProcedureResult) -> dict:
    """Per-position residuals before/after compensation, per triad."""
    from workbench.plots.turntable import plot_residuals

    return {f"{name}_residuals": plot_residuals(fit) for name, fit in result.payload.items()}
