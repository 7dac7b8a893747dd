"""Thermal measurements from a session: soak points and ramp windows.

:func:`soak_groups`, :func:`soak_points` (turntable estimators at each soak, :class:`SoakPoint`,
:class:`SoakGroup`) and :func:`ramp_series` (windows of a continuous ramp, :class:`RampSeries`).
Part of :mod:`workbench.analysis.thermal`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from workbench.analysis.thermal_settling import settling
from workbench.errors import AnalysisError, SessionError


# from a session: soak points and ramp windows
@dataclass(frozen=True)
class SoakPoint:
    """Estimates of one triad at one soak (SI; ``scale`` = diag of M, NaN where not observed).

    ``temperature_c`` is the mean unit temperature over the measurement steps and
    ``rate_c_per_min`` its slope there; ``settle_time_s`` the time the soak step took to settle
    (None when it never did); ``settled`` = ``|rate_c_per_min|`` below the tolerance.

    ``elapsed_s`` the mean time of the measurement steps since the session started (the bias
    random walk since power-on grows with it, :func:`with_bias_random_walk`).

    ``direction`` +1 when the unit approached this temperature from below (up branch),
    -1 from above (down branch), 0 when it did not move (first soak at ambient).
    """

    triad: str
    soak_step: int
    steps: tuple[int, ...]
    setpoint_c: float | None
    temperature_c: float
    rate_c_per_min: float
    settle_time_s: float | None
    direction: int
    bias: np.ndarray
    bias_sigma: np.ndarray
    scale: np.ndarray
    scale_sigma: np.ndarray
    settled: bool
    elapsed_s: float = float("nan")  # mean time of the measurement steps since the session's first sample


@dataclass(frozen=True)
class SoakGroup:
    """A soak step and the measurement steps that follow it at the same setpoint."""

    soak_step: int
    setpoint_c: float | None
    steps: tuple[int, ...]
    found: tuple[int, ...] | None = None  # soak not labelled: the group's steps taken as its soak (from the data)


def _require_temp(session, steps) -> None:
    if "temp" not in session.samples.columns:
        where = f"step(s) {', '.join(str(s) for s in steps)}" if steps else "all steps"
        raise SessionError(f"{session.name}: column temp (unit temperature, °C) is missing; "
                           f"a thermal analysis needs it ({where})")


SAME_TEMP_C = 2.0  # °C: consecutive holds without setpoints whose unit temperatures differ less are one soak


def soak_groups(session, settle_tol_c_per_min: float = 0.05, settle_window_s: float = 120.0) -> list[SoakGroup]:
    """Group the session's steps: each ``soak`` step with the non-soak, non-ramp steps after it.

    A session without ``soak`` steps (other labs' software does not label them) is grouped by
    :func:`found_soak_groups`: the soak is found from the data."""
    if not any(st.kind == "soak" for st in session.steps):
        return found_soak_groups(session, settle_tol_c_per_min, settle_window_s)
    groups: list[SoakGroup] = []
    for st in sorted(session.steps, key=lambda s: s.t_start):
        if st.kind == "soak":
            groups.append(SoakGroup(st.index, st.temperature_c, ()))
        elif st.kind == "ramp":
            groups.append(SoakGroup(-1, None, ()))  # a ramp ends the current soak group
        elif groups and groups[-1].soak_step >= 0:
            g = groups[-1]
            groups[-1] = SoakGroup(g.soak_step, g.setpoint_c, (*g.steps, st.index))
    return [g for g in groups if g.steps]


def found_soak_groups(session, settle_tol_c_per_min: float = 0.05, settle_window_s: float = 120.0) -> list[SoakGroup]:
    """Soaks of a session without soak steps, from the data (at least two, else none).

    Consecutive static and rate steps (a ramp ends a group) belong together while their chamber setpoint
    (``temperature_c``) stays the same or, without setpoints, while their mean unit temperature stays
    within :data:`SAME_TEMP_C` of the group's first. In each group the leading steps are the soak while
    the unit temperature over the remaining steps still moves (regression slope above the settling
    tolerance by more than its 2 sigma, the soak analysis's own test); the rest are measured. A group
    that never settles keeps all its steps (the soak analysis then flags it unsettled). ``found`` holds
    all the group's steps (their temperature record stands for the soak's).
    """
    if session.samples is None or "temp" not in session.samples.columns:
        return []
    labels = session.samples["step"].to_numpy()
    t_all, temp_all = session.samples["t"].to_numpy(float), session.samples["temp"].to_numpy(float)
    runs: list[list] = []
    key0 = None
    for st in sorted(session.steps, key=lambda s: s.t_start):
        if st.kind not in ("static", "rate"):
            key0 = None
            continue
        sel = labels == st.index
        if not sel.any():
            continue
        mean_temp = float(temp_all[sel].mean())
        same = (key0 is not None and (st.temperature_c == key0[0] if st.temperature_c is not None
                                      else key0[0] is None and abs(mean_temp - key0[1]) < SAME_TEMP_C))
        if not same:
            runs.append([])
            key0 = (st.temperature_c, mean_temp)
        runs[-1].append(st)
    if len(runs) < 2:
        return []
    groups = []
    for run in runs:
        idx = [st.index for st in run]
        measured = idx
        for k in range(len(idx)):  # the leading steps while the rest's temperature still moves are the soak
            sel = np.isin(labels, idx[k:])
            if _settled(t_all[sel], temp_all[sel], settle_tol_c_per_min):
                measured = idx[k:]
                break
        groups.append(SoakGroup(idx[0], run[0].temperature_c, tuple(measured), tuple(idx)))
    return groups


def _settled(t: np.ndarray, temp: np.ndarray, tol_c_per_min: float) -> bool:
    """Whether the unit temperature's regression slope is below ``tol_c_per_min`` (°C/min) within its 2 sigma
    (the soak analysis's own test of its measurement steps); records under 10 s count as settled."""
    if len(t) <= 3 or t[-1] - t[0] < 10.0:
        return True
    p, cov = np.polyfit(t - t[0], temp, 1, cov=True)
    return abs(p[0] * 60.0) - 2.0 * float(np.sqrt(cov[0, 0])) * 60.0 < tol_c_per_min


def _samples_of(session, steps) -> np.ndarray:
    return np.isin(session.samples["step"].to_numpy(), list(steps))


def _turntable():
    try:
        from workbench.analysis import turntable
    except ImportError as exc:  # written concurrently; the soak analysis needs it
        raise AnalysisError(f"soak analysis needs workbench.analysis.turntable ({exc})") from None
    return turntable


def soak_points(session, triads=("gyro", "accel"), settle_tol_c_per_min: float = 0.05,
                settle_window_s: float = 120.0, position_sigma: float | str = 0.0,
                bias_instability: Mapping[str, np.ndarray | None] | None = None
                ) -> tuple[dict[str, list[SoakPoint]], list[str]]:
    """Per-soak bias and scale factor of each triad, from the turntable estimators.

    For each soak group the accelerometer is fitted with ``fit_accel`` on the group's static
    steps; the gyro bias with ``fit_gyro_static`` on the same steps and, when the group has
    rate steps, the gyro scale factor with ``fit_gyro_rate`` (else not observed, NaN). The
    ``position_sigma`` (rad, or ``"auto"``) is the fixture's 1-sigma repeatability passed to the
    turntable estimators; ``bias_instability`` maps a triad to its Allan bias instability B (SI,
    scalar or (3,)), the floor of each soak's bias sigma (``turntable.fit_accel``). The soak's temperature is the mean unit temperature over its
    measurement steps; a soak whose
    unit temperature still moves
    during the measurement steps (regression slope at or above ``settle_tol_c_per_min``) is
    reported in the warnings naming the step and flagged ``settled=False`` (left out of the
    fits); the soak step's own settling time (:func:`settling`) is kept for the report.
    Returns ({triad: [SoakPoint]}, warnings).
    """
    tt = _turntable()
    groups = soak_groups(session, settle_tol_c_per_min, settle_window_s)
    if not groups:
        raise SessionError(f"{session.name}: no soak step followed by measurement steps, and no soaks found from "
                           "the data (holds at two or more setpoints or unit temperatures)")
    _require_temp(session, [g.soak_step for g in groups])
    t_all = session.samples["t"].to_numpy(float)
    temp_all = session.samples["temp"].to_numpy(float)
    out: dict[str, list[SoakPoint]] = {t: [] for t in triads}
    warnings: list[str] = []
    hidden: dict[str, list] = {t: [] for t in triads}  # per soak: step, hideable bias instability (3,), dwell s
    prev_temp = None
    for g in groups:
        soak_sel = _samples_of(session, [g.soak_step] if g.found is None else g.found)
        meas_sel = _samples_of(session, g.steps)
        ts, temps = t_all[soak_sel], temp_all[soak_sel]
        tm, tempm = t_all[meas_sel], temp_all[meas_sel]
        st = settling(ts, temps, settle_tol_c_per_min, settle_window_s) if len(ts) > 2 else None
        settle_time = None if st is None or not st.settled else st.t_settled - ts[0]
        rate_se = 0.0
        if len(tm) > 3 and tm[-1] - tm[0] >= 10.0:
            p, cov = np.polyfit(tm - tm[0], tempm, 1, cov=True)
            rate, rate_se = float(p[0] * 60.0), float(np.sqrt(cov[0, 0]) * 60.0)
        else:  # measurement too short to tell: the soak's own final slope
            rate = st.final_rate_c_per_min if st is not None else 0.0
        # unsettled only when the slope exceeds the tolerance by more than its 2-sigma
        # (the unit's thermometer noise makes a short regression slope uncertain)
        settled = abs(rate) - 2.0 * rate_se < settle_tol_c_per_min
        if not settled:
            how = "never settled" if settle_time is None else f"settled after {settle_time:.0f} s"
            warnings.append(f"step {g.soak_step} (soak {g.setpoint_c} °C): unit temperature did not settle: "
                            f"{rate:.3g} ± {rate_se:.2g} °C/min over measurement steps {g.steps[0]}-{g.steps[-1]} (tolerance "
                            f"{settle_tol_c_per_min} °C/min; soak step {how}); soak left out of the fit")
        mean_t = float(tempm.mean())
        start_t = float(temps[0]) if len(temps) else mean_t
        ref = prev_temp if prev_temp is not None else start_t
        move = mean_t - ref
        direction = 0 if abs(move) < 0.5 else (1 if move > 0 else -1)
        prev_temp = mean_t
        statics = [i for i in g.steps if session.step(i).kind == "static"]
        rates = [i for i in g.steps if session.step(i).kind == "rate"]
        for triad in triads:
            if triad == "accel":
                fit = tt.fit_accel(session, steps=statics, position_sigma=position_sigma,
                                   bias_instability=(bias_instability or {}).get("accel"), warn_hidden_floor=False)
                bias, bias_s = fit.bias, fit.bias_sigma
                scale, scale_s = np.diag(fit.scale_misalignment), np.diag(fit.scale_misalignment_sigma)
            else:
                rfit = tt.fit_gyro_rate(session, steps=rates, position_sigma=position_sigma) if rates else None
                m = None if rfit is None else np.where(np.isfinite(rfit.scale_misalignment_sigma),
                                                       rfit.scale_misalignment, 0.0)
                fit = tt.fit_gyro_static(session, steps=statics, scale_misalignment=m,
                                         bias_instability=(bias_instability or {}).get("gyro"),
                                         warn_hidden_floor=False)
                bias, bias_s = fit.bias, fit.bias_sigma
                scale = np.full(3, np.nan) if rfit is None else np.diag(rfit.scale_misalignment)
                scale_s = np.full(3, np.nan) if rfit is None else np.diag(rfit.scale_misalignment_sigma)
            warnings += [f"soak step {g.soak_step}: {w}" for w in fit.warnings]
            hidden[triad].append((g.soak_step, np.array(fit.notes["hidden_bias_instability"], float),
                                  min(session.step(i).duration for i in statics)))
            out[triad].append(SoakPoint(triad, g.soak_step, g.steps, g.setpoint_c, mean_t, rate, settle_time,
                                        direction,
                                        np.asarray(bias, float), np.asarray(bias_s, float),
                                        np.asarray(scale, float).copy(), np.asarray(scale_s, float).copy(), settled,
                                        float(tm.mean() - t_all[0])))
    # the first soak (usually at ambient) takes the direction of the next one's approach
    for pts in out.values():
        for i, p in enumerate(pts):
            if p.direction == 0 and i + 1 < len(pts) and pts[i + 1].direction != 0:
                pts[i] = replace(p, direction=pts[i + 1].direction)
    # one warning per triad for the soaks whose dwells could hide a bias instability (largest per axis)
    for triad, per_soak in hidden.items():
        steps = [step for step, b, _ in per_soak if np.isfinite(b).any()]
        if steps:
            with np.errstate(all="ignore"):
                worst = np.nanmax(np.array([b for _, b, _ in per_soak]), axis=0)
            what = "accelerometer fit" if triad == "accel" else "gyro static fit"
            warnings += tt.hidden_floor_warning(worst, None, min(d for _, _, d in per_soak),
                                                "mg" if triad == "accel" else "deg/h",
                                                f"soak steps {', '.join(map(str, steps))}: {what}")
    return out, warnings


@dataclass(frozen=True)
class RampSeries:
    """Windowed means over ramp steps: unit temperature, its rate and the triad's bias.

    ``bias`` (N, 3) SI = mean output minus ``(I + M_ref)`` times the known input (Earth rate or
    gravity in the body frame); ``direction`` +1 rising, -1 falling; ``steps`` the ramp step of
    each window; ``elapsed_s`` the window's mean time since the session's first sample.
    """

    triad: str
    temperature_c: np.ndarray
    rate_c_per_min: np.ndarray
    bias: np.ndarray
    bias_sigma: np.ndarray
    direction: np.ndarray
    steps: np.ndarray
    elapsed_s: np.ndarray


def _ramp_runs(ramps) -> list[list]:
    """Consecutive ramp steps that belong to one chamber ramp (same target and rate)."""
    runs: list[list] = []
    for st in ramps:
        key = (st.extra.get("ramp_to_c"), st.extra.get("ramp_rate_c_per_min"))
        if runs and (runs[-1][0].extra.get("ramp_to_c"), runs[-1][0].extra.get("ramp_rate_c_per_min")) == key:
            runs[-1].append(st)
        else:
            runs.append([st])
    return runs


def _ramp_lag_warnings(session, ramps, lag_tolerance: float) -> list[str]:
    """Warnings for ramps whose unit temperature rate falls short of the commanded rate."""
    out = []
    for run in _ramp_runs(ramps):
        commanded = run[0].extra.get("ramp_rate_c_per_min")
        sel = _samples_of(session, [s.index for s in run])
        t = session.samples["t"].to_numpy(float)[sel]
        temp = session.samples["temp"].to_numpy(float)[sel]
        if commanded is None or len(t) < 3:
            continue
        measured = (temp[-1] - temp[0]) / (t[-1] - t[0]) * 60.0
        if abs(measured) < (1.0 - lag_tolerance) * abs(float(commanded)):
            names = f"{run[0].index}" if len(run) == 1 else f"{run[0].index}-{run[-1].index}"
            out.append(f"step {names} (ramp to {run[0].extra.get('ramp_to_c')} °C): unit temperature moved at "
                       f"{measured:.3g} °C/min for a commanded {float(commanded):.3g} °C/min: ramp too fast for "
                       "the unit's thermal lag (bias is then fitted against a temperature that is not the "
                       "sensor's own)")
    return out


def ramp_series(session, triad: str, window_s: float = 60.0, reference=None,
                lag_tolerance: float = 0.2) -> tuple[RampSeries, list[str]]:
    """Bias of ``triad`` against the unit temperature over the session's ``ramp`` steps.

    ``reference`` is a TriadModel (e.g. from a turntable calibration) whose ``I + M`` maps the
    known input (Earth rate in the body frame for the gyro, specific force for the
    accelerometer) to the output and whose gyro ``G`` removes the g-sensitivity ``G f``;
    None = identity and no ``G`` (the gyro "bias" then includes ``G f`` of the position).
    For an accelerometer held in one position the bias of an axis along gravity absorbs the
    scale-factor change times g (a warning says so). A ramp whose unit temperature rate falls
    short of the commanded rate by more than ``lag_tolerance`` (fraction), i.e. too fast for
    the unit's thermal lag, is reported in the warnings naming the step.
    """
    from workbench.earth import earth_rate_ned

    ramps = sorted(session.steps_of_kind("ramp"), key=lambda s: s.t_start)
    if not ramps:
        raise SessionError(f"{session.name}: no ramp step")
    _require_temp(session, [s.index for s in ramps])
    warnings = _ramp_lag_warnings(session, ramps, lag_tolerance)
    gain = np.eye(3) if reference is None else np.eye(3) + np.asarray(reference.scale_misalignment, float)
    gsens = None if reference is None else reference.g_sensitivity
    rows = []
    g = session.site.gravity
    t0 = float(session.samples["t"].iloc[0])
    for st in ramps:
        df = session.step_samples(st.index)
        t, temp = df["t"].to_numpy(float), df["temp"].to_numpy(float)
        y = df[["gx", "gy", "gz"] if triad == "gyro" else ["ax", "ay", "az"]].to_numpy(float)
        angle = df["table_angle"].to_numpy(float) if "table_angle" in df.columns else np.full(len(t), st.table_angle)
        idx = np.floor((t - t[0]) / window_s).astype(int)
        for w in np.unique(idx):
            sel = idx == w
            if sel.sum() < 3 or np.ptp(angle[sel]) > 1e-6 or t[sel][-1] - t[sel][0] < 0.5 * window_s:
                continue
            force = session.table_attitude(st, float(angle[sel][0])).inv().apply([0.0, 0.0, -g])
            if triad == "gyro":
                true = session.attitude(st, float(angle[sel][0])).inv().apply(earth_rate_ned(session.site.latitude))
                known = gain @ true + (0.0 if gsens is None else gsens @ force)
            else:
                known = gain @ force
            slope = np.polyfit(t[sel] - t[sel][0], temp[sel], 1)[0] * 60.0
            n = sel.sum()
            rows.append((temp[sel].mean(), slope, *(y[sel].mean(0) - known),
                         *(y[sel].std(0, ddof=1) / np.sqrt(n)), st.index, t[sel].mean() - t0))
    if not rows:
        raise AnalysisError(f"{session.name}: ramp steps give no static window of {window_s} s")
    a = np.array(rows)
    rate = a[:, 1]
    direction = np.sign(rate)
    if triad == "accel":
        warnings.append("accel ramp fit: the bias of an axis along gravity includes the scale-factor "
                        "change times g (not separable in one position)")
    return RampSeries(triad, a[:, 0], rate, a[:, 2:5], a[:, 5:8], direction, a[:, 8].astype(int), a[:, 9]), warnings
