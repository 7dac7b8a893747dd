"""Gyro scale factor and misalignment from hand-made 360° turns (Ferraris method), and their checks.

For sessions without a rate table (e.g. the imucal recording, shared/data/imucal_ferraris/):
each turn step is one rotation by a known angle ``theta_k`` (body frame, rad; step keys
``turn_deg`` + ``axis`` from an import profile, else ``revolutions`` and the sign of
``table_rate`` about the mount's table axis). With the bias ``b`` and g-sensitivity ``G`` of a
static fit and the compensated accelerometer ``f(t)``, the integral over turn ``k``::

    A_k = sum_t (y(t) - b - G f(t)) dt = (I + M) (theta_k + E_k)          (Ferraris et al. 1995)

so ``I + M = A Theta^-1`` with ``A = [A_1 A_2 A_3]``, ``Theta = [theta_1 + E_1 ...]``. ``E_k`` is
the Earth rate integrated over the turn in body axes (:func:`turn_earth_rate`): the static fit
that gives ``b`` removed the Earth rate from the bias, so the turn must have it removed too, or
the scale factor about a vertical turn axis carries ``Omega_e sin(lat) T / 360°`` (30 ppm for a
4-s turn at 40.8°). When the static fit left the Earth rate in ``b`` and ``G`` (azimuth unknown,
``earth_rate=ignore``), the turn's bias error is bounded by ``Omega_e T`` and widens the sigma.
The 1-sigma of each column comes from the bias and G uncertainty times the turn duration and
the white noise integrated over it, and a tilt of the turn axis (by default the position tilt of
the accelerometer fit); it does not include the error of the turn angle itself,
which the data cannot observe: :func:`turn_checks` measures how far each hand-made turn is
from the assumed one (motion just before and after the section, wobble of the rotation axis,
tilt of the turn axis from the vertical, change of the gravity direction across the turn).

Public: :func:`fit_gyro_turns`, :func:`turn_earth_rate`, :class:`TurnCheck`, :func:`turn_checks`,
:func:`turn_angle`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from workbench.analysis.position_check import step_name
from workbench.analysis.turntable import AXES, TriadFit, check_site
from workbench.earth import EARTH_RATE, earth_rate_ned
from workbench.errors import AnalysisError
from workbench.model import TriadModel
from workbench.session import ACCEL, GYRO, Session, StepRecord


def turn_angle(step: StepRecord) -> np.ndarray:
    """Rotation vector (3,) rad, body frame, that the turn ``step`` is meant to make."""
    if "turn_deg" in step.extra and "axis" in step.extra:
        axis = str(step.extra["axis"])
        if axis not in AXES:
            raise AnalysisError(f"{step_name(step)}: axis {axis!r} is not x, y or z")
        return np.radians(float(step.extra["turn_deg"])) * np.eye(3)[AXES.index(axis)]
    revs = float(step.extra.get("revolutions", 1.0))
    return np.asarray(step.mount).T @ np.array([0.0, 0.0, 2 * np.pi * revs * np.sign(step.table_rate)])


@dataclass(frozen=True)
class TurnEarthRate:
    """The Earth rate integrated over one turn, body frame (rad), and what is not known of it.

    ``integral`` (3,) rad: the part modelled; ``variance`` (3,) rad^2: the part the data cannot
    pin down (unknown heading of the horizontal Earth rate, or the Earth rate left in the bias);
    ``method``: how it was obtained.
    """

    integral: np.ndarray
    variance: np.ndarray
    method: str


def turn_earth_rate(session: Session, step: StepRecord, rate: np.ndarray, f: np.ndarray,
                    modelled: bool) -> TurnEarthRate:
    """Earth rate integrated over turn ``step`` (body frame, rad), as :func:`fit_gyro_turns` needs it.

    ``rate`` (N, 3) rad/s: the gyro with bias and g-sensitivity removed; ``f`` (N, 3) m/s^2: the
    compensated accelerometer; ``modelled``: whether the static fit removed the Earth rate from
    the bias. Three cases:

    - modelled, table azimuth and ``table_angle`` known: the exact projection
      ``sum_t C_bn(t)' w_ie^n dt`` along the recorded table angle;
    - modelled, no table (a hand-made turn): the vertical part ``w_ie,down d_b(t)`` with the down
      direction ``d_b = -f/|f|`` from the accelerometer; the horizontal part turns with the body
      and its heading is unknown, but its magnitude ``Omega_e cos(lat) |sum_t exp(i psi_t) dt|``
      (``psi`` the angle turned so far) is not: it enters as variance perpendicular to the axis;
    - not modelled: the bias and ``G`` hold the Earth rate of the positions, so the turn's
      integral is off by up to ``Omega_e T`` per axis: a uniform bound, variance ``(Omega_e T)^2 / 3``.
    """
    dt = 1.0 / session.sample_rate_hz
    duration = len(rate) * dt
    if not modelled:
        return TurnEarthRate(np.zeros(3), np.full(3, (EARTH_RATE * duration) ** 2 / 3.0),
                             "not modelled: bias and G hold the positions' Earth rate; bound Omega_e T")
    w_ie = earth_rate_ned(session.site.latitude)
    samples = session.step_samples(step.index)
    if session.site.table_zero_azimuth is not None and "table_angle" in samples.columns:
        angle = samples["table_angle"].to_numpy(float)
        integral = session.attitude(step, angle[:, None]).inv().apply(w_ie).sum(axis=0) * dt
        return TurnEarthRate(integral, np.zeros(3), "modelled along the recorded table angle")
    down = -f / np.linalg.norm(f, axis=1, keepdims=True)
    integral = w_ie[2] * down.sum(axis=0) * dt
    axis = down.mean(axis=0) / np.linalg.norm(down.mean(axis=0))
    psi = np.cumsum(rate @ axis) * dt
    horizontal = abs(np.sum(np.exp(1j * psi)) * dt) * abs(w_ie[0])
    return TurnEarthRate(integral, horizontal**2 / 2.0 * (1.0 - axis**2),
                         "vertical part modelled from the accelerometer; horizontal heading unknown")


def _white_var(session: Session, static: TriadFit) -> np.ndarray:
    """Per-sample gyro white-noise variance (3,) (rad/s)^2 from the static steps (difference estimator)."""
    used = static.residuals.loc[static.residuals["used"], "step"]
    d = np.concatenate([np.diff(session.gyro(int(i)), axis=0) for i in used])
    return d.var(axis=0) / 2.0


def fit_gyro_turns(session: Session, static: TriadFit, accel: TriadFit,
                   steps: list[int] | None = None, axis_sigma: float | None = None,
                   nonlinearity_sigma: np.ndarray | float | None = None) -> TriadFit:
    """Gyro ``M`` (full 3x3) from three turns, with bias and ``G`` taken from ``static``.

    ``static``: :func:`workbench.analysis.turntable.fit_gyro_static` result; ``accel``: the
    accelerometer fit used to compensate the specific force during the turns. ``steps``:
    the turn steps (None = all rate steps). Returns a gyro :class:`TriadFit` (nonlinearity
    not observed); its residual table holds the static rows and one row per turn (mean rate
    over the turn, rad/s).

    ``axis_sigma`` (rad): 1-sigma tilt of each turn's axis in the body (fixture or hand);
    a tilt leaks ``|theta| e`` into the two other axes, so it adds ``(|theta| s)^2`` to their
    variance (``(|theta| s^2 / 2)^2`` along the axis). Default: the accelerometer fit's
    position tilt (``accel.notes["position_sigma_rad"]``).

    ``nonlinearity_sigma`` (1/(rad/s), scalar or (3,)): 1-sigma of the unit's nonlinearity
    ``n`` (``measured += n u^2``). Turns at one rate cannot tell ``n`` from the scale factor: the
    fitted scale factor is the effective one at the turn rate, ``s + n w``; with this value the
    sigma of each diagonal element includes ``n_sigma sum_t u_j^2 dt`` over the turn about it.
    Without it a warning says how the scale factor is to be read.
    """
    check_site(session)
    recs = session.steps_of_kind("rate") if steps is None else [session.step(i) for i in steps]
    if len(recs) < 3:
        raise AnalysisError(f"{session.name}: Ferraris gyro fit needs three turns about independent axes, "
                            f"found {len(recs)} rate step(s)")
    theta = np.column_stack([turn_angle(r) for r in recs])  # (3, K)
    if np.linalg.matrix_rank(theta) < 3:
        raise AnalysisError(f"{session.name}: the turns ({', '.join(step_name(r) for r in recs)}) "
                            "do not span three axes")
    dt = 1.0 / session.sample_rate_hz
    acc_model = accel.model()
    bias, g = static.bias, static.g_sensitivity if static.g_sensitivity is not None else np.zeros((3, 3))
    g_sig = np.nan_to_num(static.g_sensitivity_sigma if static.g_sensitivity_sigma is not None else np.zeros((3, 3)))
    white = _white_var(session, static)
    tilt = float(accel.notes.get("position_sigma_rad", 0.0)) if axis_sigma is None else float(axis_sigma)
    modelled = str(static.notes.get("earth_rate", "")).startswith("modelled")
    n_sig = (np.zeros(3) if nonlinearity_sigma is None
             else np.broadcast_to(np.asarray(nonlinearity_sigma, float), (3,)))
    integrals, variances, durations, earth = [], [], [], []
    for k, r in enumerate(recs):
        angle = np.linalg.norm(theta[:, k])
        along = (theta[:, k] / angle) ** 2
        axis_var = (angle * tilt) ** 2 * (1 - along) + (angle * tilt**2 / 2) ** 2 * along
        y = session.gyro(r.index)
        f = acc_model.compensate(session.accel(r.index))
        rate = y - bias - f @ g.T
        earth.append(turn_earth_rate(session, r, rate, f, modelled))
        integrals.append(np.sum(rate, axis=0) * dt)
        t = len(y) * dt
        f_mean = f.mean(axis=0)
        variances.append((t * static.bias_sigma) ** 2 + t * dt * white + (t * g_sig @ np.abs(f_mean)) ** 2 + axis_var
                         + earth[-1].variance + (n_sig * np.sum(rate**2, axis=0) * dt) ** 2)
        durations.append(t)
    a = np.column_stack(integrals)  # (3, K)
    theta_true = theta + np.column_stack([e.integral for e in earth])  # the body turned by theta and by the Earth
    pinv = np.linalg.pinv(theta_true)  # (K, 3): I + M = A pinv(Theta)
    gain = a @ pinv
    m_sigma = np.zeros((3, 3))
    for j in range(3):
        cov = pinv.T @ np.diag([v[j] for v in variances]) @ pinv
        m_sigma[j] = np.sqrt(np.diag(cov))
    m = gain - np.eye(3)
    model = TriadModel(bias, m, np.zeros(3), g)
    ref = (theta_true / np.array(durations)).T
    raw = np.array([session.gyro(r.index).mean(axis=0) for r in recs])
    comp = np.array([model.compensate(session.gyro(r.index),
                                      specific_force=acc_model.compensate(session.accel(r.index))).mean(axis=0)
                     for r in recs])
    rows = pd.DataFrame({"step": [r.index for r in recs], "label": [r.label or r.kind for r in recs],
                         "kind": [r.kind for r in recs], "used": True,
                         **{f"ref_{ax}": ref[:, j] for j, ax in enumerate(AXES)},
                         **{f"before_{ax}": raw[:, j] - ref[:, j] for j, ax in enumerate(AXES)},
                         **{f"after_{ax}": comp[:, j] - ref[:, j] for j, ax in enumerate(AXES)},
                         **{f"sigma_{ax}": [np.sqrt(v[j]) / t for v, t in zip(variances, durations)]
                            for j, ax in enumerate(AXES)},
                         "before_norm": np.linalg.norm(raw, axis=1) - np.linalg.norm(ref, axis=1),
                         "after_norm": np.linalg.norm(comp, axis=1) - np.linalg.norm(ref, axis=1)})
    warnings = list(static.warnings) + [
        f"{session.name}: scale factor and misalignment assume each turn is exactly "
        f"{', '.join(f'{np.degrees(np.linalg.norm(theta[:, k])):.0f}°' for k in range(theta.shape[1]))} about its "
        "body axis; their sigma holds the sensor noise only (see the turn checks)"]
    if nonlinearity_sigma is None:
        rates = ", ".join(f"{np.degrees(np.linalg.norm(theta[:, k]) / durations[k]):.0f}°/s" for k in range(len(recs)))
        warnings.append(f"{session.name}: gyro nonlinearity not observed by turns at one rate ({rates}): the scale "
                        "factor is the effective one at that rate (s + n w); give the unit's nonlinearity to "
                        "include it in the sigma")
    if not modelled:
        bound = EARTH_RATE * max(durations) / (2 * np.pi)
        warnings.append(f"{session.name}: Earth rate not modelled in the turns (the static fit left it in the bias): "
                        f"the scale factor carries up to Ω_e·T / 360° = {bound * 1e6:.3g} ppm, included in its sigma")
    notes = {**dict(static.notes), "turn_steps": [r.index for r in recs], "turn_axis_sigma_rad": tilt,
             "turn_durations_s": durations, "method": "Ferraris: integrated turns against the known angle",
             "turn_earth_rate": earth[0].method,
             "turn_earth_rate_rad": [e.integral.tolist() for e in earth]}
    return replace(static, scale_misalignment=m, scale_misalignment_sigma=m_sigma,
                   residuals=pd.concat([static.residuals, rows], ignore_index=True),
                   warnings=tuple(warnings), notes=notes)


@dataclass(frozen=True)
class TurnCheck:
    """How far one hand-made turn is from the turn the fit assumes (rad, rad/s, body frame).

    ``angle``: integral of the compensated gyro about the nominal axis (signed, rad);
    ``integral`` (3,) the whole compensated integral; ``closure``: rotation angle left after
    composing the compensated rates over the turn (0 for an exact closed turn);
    ``wobble_rms``: |rate|-weighted rms angle between the instantaneous rate and the line of
    the mean turn axis; ``backward``: angle turned against the turn's direction (a jerky
    hand turn); ``axis_tilt``: angle between the nominal turn axis and the vertical measured by the
    compensated accelerometer just before the turn (how far the axis was from vertical);
    ``gravity_change``: angle between the gravity directions before and after the turn;
    ``motion_before``/``motion_after``: compensated gyro angle (norm of the integral) in the
    windows just before/after the section, and ``rate_rms_before``/``rate_rms_after``.
    NaN where the window has no samples.
    """

    step: int
    label: str
    nominal: np.ndarray
    integral: np.ndarray
    angle: float
    closure: float
    wobble_rms: float
    backward: float
    axis_tilt: float
    gravity_change: float
    motion_before: float
    motion_after: float
    rate_rms_before: float
    rate_rms_after: float

    def to_dict(self) -> dict:
        """JSON-ready dict (SI)."""
        out = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in self.__dict__.items()}
        return {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in out.items()}


def _window(session: Session, t0: float, t1: float) -> pd.DataFrame:
    t = session.samples["t"].to_numpy()
    return session.samples[(t >= t0) & (t < t1)]


def _angle_between(u: np.ndarray, v: np.ndarray) -> float:
    return float(np.arctan2(np.linalg.norm(np.cross(u, v)), np.dot(u, v)))


def turn_checks(session: Session, gyro: TriadModel, accel: TriadModel, steps: list[int] | None = None,
                window_s: float = 1.0) -> list[TurnCheck]:
    """Checks of each turn step with the fitted models (see :class:`TurnCheck`).

    ``window_s``: length of the windows just before and after each turn section, s.
    """
    recs = session.steps_of_kind("rate") if steps is None else [session.step(i) for i in steps]
    dt = 1.0 / session.sample_rate_hz
    out = []
    for r in recs:
        nominal = turn_angle(r)
        f = accel.compensate(session.accel(r.index))
        w = gyro.compensate(session.gyro(r.index), specific_force=f)
        integral = w.sum(axis=0) * dt
        axis = nominal / np.linalg.norm(nominal)
        steps_rot = Rotation.from_rotvec(w * dt)
        total = Rotation.identity()
        for k in range(len(steps_rot)):
            total = total * steps_rot[k]
        mean_axis = integral / np.linalg.norm(integral)
        speed = np.linalg.norm(w, axis=1)
        off_axis = np.arcsin(np.clip(np.linalg.norm(np.cross(w, mean_axis), axis=1) / np.maximum(speed, 1e-300), 0, 1))
        wobble = float(np.sqrt(np.sum(speed * off_axis**2) / np.sum(speed)))
        along = w @ axis
        backward = float(np.sum(np.abs(along[along < 0] if integral @ axis > 0 else along[along > 0])) * dt)
        before = _window(session, r.t_start - window_s, r.t_start)
        after = _window(session, r.t_end, r.t_end + window_s)
        stats = []
        for win in (before, after):
            if len(win) < 2:
                stats.append((np.nan, np.nan, np.full(3, np.nan)))
                continue
            fw = accel.compensate(win[ACCEL].to_numpy(float))
            ww = gyro.compensate(win[GYRO].to_numpy(float), specific_force=fw)
            stats.append((float(np.linalg.norm(ww.sum(axis=0) * dt)), float(np.sqrt(np.mean(np.sum(ww**2, axis=1)))),
                          fw.mean(axis=0)))
        up_before, up_after = stats[0][2], stats[1][2]
        tilt = (min(_angle_between(up_before, axis), _angle_between(up_before, -axis))
                if np.all(np.isfinite(up_before)) else np.nan)
        change = (_angle_between(up_before, up_after)
                  if np.all(np.isfinite(up_before)) and np.all(np.isfinite(up_after)) else np.nan)
        out.append(TurnCheck(r.index, r.label or r.kind, nominal, integral, float(integral @ axis),
                             float(total.magnitude()), wobble, backward, tilt, change, stats[0][0], stats[1][0],
                             stats[0][1], stats[1][1]))
    return out
