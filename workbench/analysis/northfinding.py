"""North-finding from Earth-rate measurements on an indexing or rotating table.

Estimators of the azimuth of the body x axis at the table's zero (clockwise from true north)
from gyro outputs against the table angle:

* maytagging, two positions 180° apart: eq. 4.6 (two horizontal axes, atan2, no latitude
  needed) and eq. 4.3 (one axis, arccos, with its ±180° ambiguity);
* multi-position and carousel: linear least squares of
  ``rate_i = b_i [+ d_i t] + g_i Omega_N cos(psi + alpha_i + a)`` over every horizontal axis
  ``i`` (``a`` table angle, ``alpha_i`` the axis direction relative to body x, ``g_i`` its
  horizontal projection), i.e. ``b + A cos(a) + B sin(a)`` per axis with ``A, B`` shared
  through ``(Omega_N cos psi, Omega_N sin psi)``;
* the redundant-gyro configuration of sec. 4.4.3: two consecutive 45° positions of a two-axis
  gyro taken as one skewed four-axis configuration (axes at psi, psi+45°, psi+90°, psi+135°),
  biases removed with a known (turn-averaged or calibrated) bias.

Frames: body x fwd, y right, z down; table-top frame x along the table's zero, z down; table
angle ``a`` positive clockwise from above; Earth rate in NED ``Omega_e (cos lat, 0, -sin lat)``.
The body rate at table angle ``a`` is ``mount.T @ (Rz(a).T Rz(az0).T Omega_ned + (0, 0, r))``
(``r`` the table rate), so axis ``i`` with table-frame direction ``mount[:, i]`` sees
``g_i Omega_N cos(az0 + alpha_i + a) - d_i (Omega_e sin lat - r)`` with ``d_i = mount[2, i]``.

Public: :class:`Observations`, :class:`AxisGeometry`, :class:`HarmonicFit`,
:class:`MaytagResult`, :class:`RedundantResult`, :func:`maytag_azimuth`,
:func:`maytag_azimuth_one_axis`, :func:`fit_harmonic`, :func:`maytag`, :func:`redundant`,
:func:`group_fits`, :func:`static_observations`, :func:`rotating_observations`,
:func:`find_north`, :class:`NorthFinding`, :func:`to_result`,
:func:`earth_rate_free_series`, :func:`sequence_table`, :func:`pairing_table`,
:func:`circular_mean`, :func:`angle_diff`, :func:`repeatability`.

References: thesis (shared/seeds/000_...) sec. 4.2 eq. 4.1-4.6, sec. 4.4.1-4.4.3,
tables 4.2-4.4.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from workbench.analysis.northfinding_theory import check_latitude
from workbench.earth import EARTH_RATE
from workbench.errors import AnalysisError
from workbench.session import Session

if TYPE_CHECKING:
    from workbench.grades import SensorSpec

STATIC_RATE_TOL = 1e-9  # rad/s: |table_rate| below this counts as static


def angle_diff(a: np.ndarray | float, b: np.ndarray | float) -> np.ndarray:
    """``a - b`` wrapped to (-pi, pi], rad."""
    return np.angle(np.exp(1j * (np.asarray(a, float) - np.asarray(b, float))))


def circular_mean(angles: np.ndarray) -> float:
    """Mean direction of ``angles`` (rad), in (-pi, pi]."""
    return float(np.angle(np.mean(np.exp(1j * np.asarray(angles, float)))))


# -- observations -------------------------------------------------------------------------

@dataclass(frozen=True)
class Observations:
    """Averaged gyro outputs against the table angle.

    Each row averages the samples of one static position or one short bin of a rotation:
    ``t`` (N,) s mid-time; ``rate`` (N, 3) rad/s body-frame gyro mean; ``cos_angle``,
    ``sin_angle`` (N,) the means of cos/sin of the table angle over the row's samples (exact
    for a bin that sweeps an arc); ``table_rate`` (N,) rad/s mean; ``duration`` (N,) s
    averaging time; ``step`` (N,) session step index; ``n`` (N,) samples averaged.
    """

    t: np.ndarray
    rate: np.ndarray
    cos_angle: np.ndarray
    sin_angle: np.ndarray
    table_rate: np.ndarray
    duration: np.ndarray
    step: np.ndarray
    n: np.ndarray

    @property
    def angle(self) -> np.ndarray:
        """Table angle of each row, rad in (-pi, pi] (from the averaged cos/sin)."""
        return np.arctan2(self.sin_angle, self.cos_angle)

    def __len__(self) -> int:
        return len(self.t)

    def subset(self, index) -> Observations:
        """Rows selected by a boolean mask or an index array."""
        return Observations(*(np.asarray(getattr(self, f))[index] for f in
                              ("t", "rate", "cos_angle", "sin_angle", "table_rate", "duration", "step", "n")))


def _concat(parts: list[Observations]) -> Observations:
    return Observations(*(np.concatenate([getattr(p, f) for p in parts]) for f in
                          ("t", "rate", "cos_angle", "sin_angle", "table_rate", "duration", "step", "n")))


class _Samples:
    """The session's samples as numpy columns, cut per step (pandas filtering per step is slow)."""

    def __init__(self, session: Session) -> None:
        df = session.samples
        self.session = session
        self.t = df["t"].to_numpy(float)
        self.gyro = df[["gx", "gy", "gz"]].to_numpy(float)
        self.accel = df[["ax", "ay", "az"]].to_numpy(float)
        self.angle = df["table_angle"].to_numpy(float) if "table_angle" in df.columns else None
        self.rate = df["table_rate"].to_numpy(float) if "table_rate" in df.columns else None
        label = df["step"].to_numpy()
        order = np.argsort(label, kind="stable")
        keys, first = np.unique(label[order], return_index=True)
        self._rows = dict(zip(keys.tolist(), np.split(order, first[1:])))

    def cut(self, st, settle_s: float, static: bool) -> dict:
        """Samples of step ``st`` after ``settle_s`` s (static: only samples with no table rate).

        Returns ``t`` s, ``gyro`` (n, 3) rad/s, ``accel`` (n, 3), ``angle`` rad (the encoder
        column, else the commanded motion), ``rate`` rad/s, and ``span`` s (step end minus
        the first usable sample, before settling is removed).
        """
        rows = self._rows.get(st.index, np.zeros(0, int))
        if static and self.rate is not None:
            rows = rows[np.abs(self.rate[rows]) < STATIC_RATE_TOL]
        t = self.t[rows]
        span = 0.0 if len(t) == 0 else st.t_end - max(st.t_start, t[0])
        if len(t):
            rows = rows[t >= max(st.t_start, t[0]) + settle_s]
            t = self.t[rows]
        angle = self.angle[rows] if self.angle is not None else st.table_angle + st.table_rate * (t - st.t_start)
        rate = self.rate[rows] if self.rate is not None else np.full(len(t), st.table_rate)
        return {"t": t, "gyro": self.gyro[rows], "accel": self.accel[rows], "angle": angle, "rate": rate,
                "span": span}


def static_observations(session: Session, settle_s: float, steps: Sequence[int] | None = None) -> Observations:
    """One row per static step: the gyro mean after ``settle_s`` seconds of settling.

    Uses the steps of kind ``static`` (or ``steps``, a list of indices). Samples with a
    recorded ``table_rate`` above 1e-9 rad/s are dropped. The angle is the mean of the
    encoder column ``table_angle`` when recorded, else the step's commanded angle. Raises
    AnalysisError naming the step when its dwell is not longer than ``settle_s``.
    """
    chosen = session.steps_of_kind("static") if steps is None else [session.step(i) for i in steps]
    if not chosen:
        raise AnalysisError(f"{session.name}: no static steps to find north from")
    data = _Samples(session)
    rows = []
    for st in chosen:
        c = data.cut(st, settle_s, static=True)
        if c["span"] <= settle_s or len(c["t"]) == 0:
            where = f"{session.name}: step {st.index} ({st.kind}{', ' + st.label if st.label else ''})"
            raise AnalysisError(f"{where}: static dwell {c['span']:.3g} s is not longer than the settling time "
                                f"{settle_s:g} s")
        n = len(c["t"])
        rows.append(Observations(np.array([c["t"].mean()]), c["gyro"].mean(axis=0)[None, :],
                                 np.array([np.cos(c["angle"]).mean()]), np.array([np.sin(c["angle"]).mean()]),
                                 np.zeros(1), np.array([n / session.sample_rate_hz]), np.array([st.index]),
                                 np.array([n])))
    return _concat(rows)


def rotating_observations(session: Session, settle_s: float, bin_deg: float = 5.0,
                          kinds: tuple[str, ...] = ("carousel",)) -> Observations:
    """Bins of the rotating steps (kind ``carousel``): gyro means over arcs of ``bin_deg``.

    The first ``settle_s`` seconds of each step (spin-up) are dropped. Each bin carries the
    exact means of cos/sin of the table angle over its samples, so the arc's averaging of the
    sinusoid is modelled, not neglected.
    """
    chosen = session.steps_of_kind(*kinds)
    if not chosen:
        raise AnalysisError(f"{session.name}: no {'/'.join(kinds)} steps to find north from")
    data = _Samples(session)
    parts = []
    for st in chosen:
        c = data.cut(st, settle_s, static=False)
        where = f"{session.name}: step {st.index} ({st.kind})"
        if c["span"] <= settle_s:
            raise AnalysisError(f"{where}: duration {c['span']:.3g} s is not longer than the settling time "
                                f"{settle_s:g} s")
        per_bin = max(1, int(round(np.radians(bin_deg) / max(abs(st.table_rate), 1e-12) * session.sample_rate_hz)))
        nb = len(c["t"]) // per_bin
        if nb < 8:
            raise AnalysisError(f"{where}: {nb} bins of {bin_deg:g}°; a carousel needs at least 8")

        def bmean(v):
            v = np.asarray(v)[:nb * per_bin]
            return v.reshape(nb, per_bin, *v.shape[1:]).mean(axis=1)

        parts.append(Observations(bmean(c["t"]), bmean(c["gyro"]), bmean(np.cos(c["angle"])),
                                  bmean(np.sin(c["angle"])), bmean(c["rate"]),
                                  np.full(nb, per_bin / session.sample_rate_hz), np.full(nb, st.index),
                                  np.full(nb, per_bin)))
    return _concat(parts)


# -- geometry -----------------------------------------------------------------------------

@dataclass(frozen=True)
class AxisGeometry:
    """Where the body gyro axes point in the table-top frame (from the mount).

    ``axis_angle`` (3,) rad: horizontal direction of each body axis relative to body x's,
    clockwise from above (y of a z-down mount is +pi/2); ``gain`` (3,) the horizontal
    projection ``|mount[:2, i]|``; ``down`` (3,) the down component ``mount[2, i]``;
    ``horizontal`` (3,) bool, axes within ``max_tilt`` of level, which sense the Earth rate;
    ``heading`` rad, direction of body x in the table frame (clockwise from the table's zero).
    """

    axis_angle: np.ndarray
    gain: np.ndarray
    down: np.ndarray
    horizontal: np.ndarray
    heading: float = 0.0

    @classmethod
    def from_mount(cls, mount: np.ndarray, max_tilt: float, where: str = "mount",
                   axes: Sequence[int] = (0, 1, 2)) -> AxisGeometry:
        """Geometry of ``mount`` (3x3 body->table-top) for the sensing ``axes``. Every sensing axis
        must be level or vertical within ``max_tilt`` (rad) and body x level (it carries the
        azimuth); else AnalysisError. Non-sensing axes (a filler channel) are never level."""
        m = np.asarray(mount, float)
        down = m[2].copy()
        tilt = np.arcsin(np.clip(np.abs(down), 0.0, 1.0))
        used = np.isin(np.arange(3), list(axes))
        horizontal = (tilt <= max_tilt) & used
        vertical = (tilt >= np.pi / 2 - max_tilt) | ~used
        if not horizontal[0]:
            raise AnalysisError(f"{where}: body x is tilted {np.degrees(tilt[0]):.2f}° from level "
                                f"(limit {np.degrees(max_tilt):.2f}°): its azimuth is not defined; "
                                "mount the unit level")
        odd = ~(horizontal | vertical)
        if odd.any():
            i = int(np.argmax(odd))
            raise AnalysisError(f"{where}: gyro axis {'xyz'[i]} is tilted {np.degrees(tilt[i]):.2f}° from level: "
                                f"axes must be level or vertical within {np.degrees(max_tilt):.2f}°")
        heading = np.arctan2(m[1], m[0])
        return cls(angle_diff(heading, heading[0]), np.hypot(m[0], m[1]), down, horizontal, float(heading[0]))


# -- closed forms (eq. 4.3, 4.6) ----------------------------------------------------------

def maytag_azimuth(rate_home: np.ndarray, rate_flipped: np.ndarray, y_clockwise: bool = True) -> float:
    """Azimuth of the body x axis at the home position from one maytag pair (thesis eq. 4.6).

    ``psi = atan2(m4 - m3, m1 - m2)`` with ``m1, m2`` the x outputs and ``m3, m4`` the y
    outputs (rad/s) at home and after the 180° index. Needs no latitude and no scale factor
    when both axes share it. ``y_clockwise``: y points 90° clockwise of x seen from above
    (z-down mount); False for z-up, where the sign of the y difference flips.

    Parameters
    ----------
    rate_home, rate_flipped : (2,) array, rad/s
        Mean x and y gyro outputs (horizontal projections) at home and after the index.

    Returns
    -------
    float, rad in (-pi, pi]
    """
    d = (np.asarray(rate_home, float) - np.asarray(rate_flipped, float)) / 2.0
    sign = 1.0 if y_clockwise else -1.0
    return float(np.arctan2(-sign * d[1], d[0]))


def maytag_azimuth_one_axis(m1: float, m2: float, latitude: float) -> tuple[float, float]:
    """The two azimuth candidates (rad) of a single horizontal gyro from one maytag pair (eq. 4.3).

    ``psi = arccos((m1 - m2) / (2 Omega_e cos lat))`` lies in [0, pi]; ``-psi`` gives the same
    outputs, so the azimuth is ambiguous: the pair (psi, -psi) is returned. A difference beyond
    the Earth rate (noise, scale-factor or latitude error) is clipped to ±1 before the arccos.
    ``m1, m2`` rad/s; ``latitude`` rad.
    """
    check_latitude(latitude)
    psi = float(np.arccos(np.clip((m1 - m2) / (2.0 * EARTH_RATE * np.cos(latitude)), -1.0, 1.0)))
    return psi, -psi


# -- least squares ------------------------------------------------------------------------

@dataclass(frozen=True)
class HarmonicFit:
    """Least-squares fit of the Earth-rate sinusoid to gyro outputs vs table angle.

    ``azimuth`` rad of the body x axis at the table's zero, clockwise from true north, in
    (-pi, pi], and ``azimuth_sigma`` (formal 1-sigma, rad, from the residual scatter of each
    axis; it assumes independent rows). ``amplitude`` rad/s, the horizontal Earth rate seen
    (``Omega_e cos lat`` for a perfect gyro). ``bias`` (3,) rad/s per body axis with
    ``bias_sigma``; ``drift`` (3,) rad/s/s (NaN when not fitted), ``t_ref`` s the time the bias
    refers to. ``residual`` (N, 3) rad/s; ``residual_std`` (3,) rad/s per axis.
    """

    azimuth: float
    azimuth_sigma: float
    amplitude: float
    amplitude_sigma: float
    bias: np.ndarray
    bias_sigma: np.ndarray
    drift: np.ndarray
    drift_sigma: np.ndarray
    t_ref: float
    residual: np.ndarray
    residual_std: np.ndarray
    n_rows: int

    def model(self, angle: np.ndarray, geometry: AxisGeometry, latitude: float) -> np.ndarray:
        """Fitted gyro output (K, 3) rad/s at static table angles ``angle`` (K,) rad, drift omitted."""
        a = np.asarray(angle, float)[:, None]
        earth = geometry.gain * self.amplitude * np.cos(self.azimuth + geometry.axis_angle + a)
        return self.bias + earth - geometry.down * EARTH_RATE * np.sin(latitude)


def _design(obs: Observations, geom: AxisGeometry, axis: int) -> np.ndarray:
    """Columns (c, s) = (Omega_N cos psi, Omega_N sin psi) for one axis: g (cos(al+a), -sin(al+a))."""
    ca, sa = np.cos(geom.axis_angle[axis]), np.sin(geom.axis_angle[axis])
    cos_t = ca * obs.cos_angle - sa * obs.sin_angle  # mean cos(alpha + a)
    sin_t = sa * obs.cos_angle + ca * obs.sin_angle  # mean sin(alpha + a)
    return geom.gain[axis] * np.column_stack([cos_t, -sin_t])


def fit_harmonic(obs: Observations, geom: AxisGeometry, latitude: float, drift: bool = False,
                 bias: np.ndarray | None = None, where: str = "fit") -> HarmonicFit:
    """Fit ``rate_i = b_i [+ d_i (t - t_ref)] + g_i Omega_N cos(psi + alpha_i + a)`` (see module doc).

    Horizontal axes share ``(Omega_N cos psi, Omega_N sin psi)``; each axis has its own bias
    (and drift with ``drift=True``). Vertical axes only give their bias (the known vertical
    Earth rate and the table rate are removed). With ``bias`` (3,) rad/s given, biases are
    not fitted but subtracted (the redundant configuration). Rows are weighted per axis by
    the inverse residual variance of a first unweighted pass. Angles rad, rates rad/s.
    """
    check_latitude(latitude, where)
    n = len(obs)
    hz = np.flatnonzero(geom.horizontal)
    t_ref = float(np.mean(obs.t))
    dt = obs.t - t_ref
    # remove the known parts: vertical Earth rate and table rate along each axis
    y = obs.rate - geom.down * (-EARTH_RATE * np.sin(latitude) + obs.table_rate[:, None])
    if bias is not None:
        y = y - np.asarray(bias, float)
    fit_bias = bias is None
    n_per = (1 + int(drift)) if fit_bias else 0
    n_par = 2 + n_per * len(hz)
    if n * len(hz) < n_par:
        raise AnalysisError(f"{where}: {n} rows x {len(hz)} level axes cannot fit {n_par} parameters")
    exact = n * len(hz) == n_par  # e.g. one maytag pair: no residual, no formal uncertainty
    if abs(np.mean(obs.cos_angle + 1j * obs.sin_angle)) > 1 - 1e-9 and fit_bias:
        raise AnalysisError(f"{where}: all rows at one table angle; bias and Earth rate are not separable")
    blocks, rhs, axis_of = [], [], []
    for k, i in enumerate(hz):
        cols = np.zeros((n, n_par))
        cols[:, :2] = _design(obs, geom, i)
        if fit_bias:
            cols[:, 2 + n_per * k] = 1.0
            if drift:
                cols[:, 3 + n_per * k] = dt
        blocks.append(cols)
        rhs.append(y[:, i])
        axis_of.append(np.full(n, i))
    a_mat, b_vec, ax = np.vstack(blocks), np.concatenate(rhs), np.concatenate(axis_of)
    w = np.ones_like(b_vec)
    for _ in range(1 if exact else 2):  # unweighted, then weighted by per-axis residual variance
        sol, *_ = np.linalg.lstsq(a_mat * w[:, None], b_vec * w, rcond=None)
        res = b_vec - a_mat @ sol
        dof = max(len(b_vec) - n_par, 1)
        var_axis = {i: max(float(np.sum(res[ax == i] ** 2)) / max(dof * np.sum(ax == i) / len(ax), 1e-12), 1e-40)
                    for i in hz}
        w = 1.0 / np.sqrt(np.array([var_axis[i] for i in ax]))
    cov = np.linalg.pinv((a_mat * w[:, None]).T @ (a_mat * w[:, None]))
    if exact:
        cov[:] = np.nan
    c, s = sol[:2]
    amp = float(np.hypot(c, s))
    if amp == 0.0:
        raise AnalysisError(f"{where}: no Earth-rate signal fitted")
    jac_az = np.array([-s, c]) / amp**2
    jac_amp = np.array([c, s]) / amp
    az_sigma = float(np.sqrt(jac_az @ cov[:2, :2] @ jac_az))
    amp_sigma = float(np.sqrt(jac_amp @ cov[:2, :2] @ jac_amp))

    residual = np.full((n, 3), np.nan)
    est_bias = np.full(3, np.nan) if fit_bias else np.asarray(bias, float).copy()
    bias_sigma = np.full(3, np.nan)
    est_drift, drift_sigma = np.full(3, np.nan), np.full(3, np.nan)
    for k, i in enumerate(hz):
        residual[:, i] = res[ax == i]
        if fit_bias:
            j = 2 + n_per * k
            est_bias[i], bias_sigma[i] = sol[j], np.sqrt(cov[j, j])
            if drift:
                est_drift[i], drift_sigma[i] = sol[j + 1], np.sqrt(cov[j + 1, j + 1])
    for i in np.flatnonzero(~geom.horizontal):  # vertical axes: mean (and drift) after the known parts
        cols = np.column_stack([np.ones(n), dt]) if drift else np.ones((n, 1))
        p, *_ = np.linalg.lstsq(cols, y[:, i], rcond=None)
        r = y[:, i] - cols @ p
        var = float(r @ r) / max(n - cols.shape[1], 1)
        pc = var * np.linalg.pinv(cols.T @ cols)
        residual[:, i] = r
        if fit_bias:
            est_bias[i], bias_sigma[i] = p[0], np.sqrt(pc[0, 0])
        if drift:
            est_drift[i], drift_sigma[i] = p[1], np.sqrt(pc[1, 1])
    return HarmonicFit(float(np.arctan2(s, c)), az_sigma, amp, amp_sigma, est_bias, bias_sigma, est_drift,
                       drift_sigma, t_ref, residual, np.sqrt(np.nanmean(residual**2, axis=0)), n)


def group_fits(obs: Observations, groups: np.ndarray, geom: AxisGeometry, latitude: float,
               where: str = "fit") -> np.ndarray:
    """Azimuth (rad) of a separate fit (bias + sinusoid, no drift) per group label, in sorted order.

    Used per lap of a carousel and per turn of a multi-position sweep.
    """
    return np.array([fit_harmonic(obs.subset(groups == g), geom, latitude, where=f"{where} group {g}").azimuth
                     for g in np.unique(groups)])


# -- maytagging ---------------------------------------------------------------------------

@dataclass(frozen=True)
class MaytagResult:
    """Maytag pairs and their azimuths (thesis sec. 4.4.2).

    ``pair_azimuth`` (P,) rad, azimuth of body x at the table's zero from each pair (eq. 4.6
    with two level axes, else eq. 4.3 with the candidate nearest the pairs' mean, see
    ``ambiguous``); ``pair_time`` (P,) s; ``pair_steps`` (P, 2) step indices;
    ``pair_amplitude`` (P,) rad/s horizontal Earth rate seen by the pair;
    ``azimuth`` rad, circular mean of the pairs; ``azimuth_sigma`` rad, their std / sqrt(P);
    ``pair_std`` rad, the std of the pairs about their mean; ``fit`` the harmonic fit of all
    positions (bias, amplitude, drift); ``ambiguous``: True for a one-axis result (eq. 4.3),
    whose azimuth may be mirrored (``-psi``).
    """

    pair_azimuth: np.ndarray
    pair_time: np.ndarray
    pair_steps: np.ndarray
    pair_amplitude: np.ndarray
    azimuth: float
    azimuth_sigma: float
    pair_std: float
    fit: HarmonicFit
    ambiguous: bool
    warnings: tuple[str, ...] = field(default=())


def maytag(obs: Observations, geom: AxisGeometry, latitude: float, index_tol: float, drift: bool = False,
           where: str = "maytagging") -> MaytagResult:
    """Azimuth from consecutive position pairs 180° apart (eq. 4.6, or eq. 4.3 with one level axis).

    Rows are paired in time order (0, 1), (2, 3), ...; each pair must be 180° apart by its
    recorded angles within ``index_tol`` (rad), else AnalysisError naming the steps. The
    pair's home angle is removed so every pair estimates the azimuth at the table's zero.
    """
    check_latitude(latitude, where)
    order = np.argsort(obs.t)
    obs = obs.subset(order)
    n_pairs = len(obs) // 2
    if n_pairs < 1:
        raise AnalysisError(f"{where}: {len(obs)} static position(s); maytagging needs at least one pair")
    warnings = []
    if len(obs) % 2:
        warnings.append(f"{where}: odd number of positions; the last (step {obs.step[-1]}) is not paired")
    hz = np.flatnonzero(geom.horizontal)
    two_axis = len(hz) >= 2
    ang = obs.angle
    pair_az, pair_amp, pair_t, pair_steps = [], [], [], []
    for k in range(n_pairs):
        i, j = 2 * k, 2 * k + 1
        sep = abs(angle_diff(ang[j] - ang[i], np.pi))
        if sep > index_tol:
            raise AnalysisError(f"{where}: steps {obs.step[i]} -> {obs.step[j]}: the index is "
                                f"{np.degrees(np.mod(ang[j] - ang[i], 2 * np.pi)):.4f}° by the encoder, not 180° "
                                f"(tolerance {np.degrees(index_tol):.3g}°)")
        d = (obs.rate[i] - obs.rate[j]) / 2.0 / np.where(geom.gain > 0, geom.gain, 1.0)
        if two_axis:
            iy = hz[1]
            psi = maytag_azimuth(np.array([d[0], d[iy]]), np.zeros(2), bool(np.sin(geom.axis_angle[iy]) > 0))
            amp = float(np.hypot(d[0], d[iy]))
        else:
            psi = maytag_azimuth_one_axis(2 * d[0], 0.0, latitude)[0]
            amp = np.nan  # one axis sees Omega_N cos(psi): the amplitude is not observed
        pair_az.append(float(angle_diff(psi, ang[i])))
        pair_amp.append(amp)
        pair_t.append(0.5 * (obs.t[i] + obs.t[j]))
        pair_steps.append((int(obs.step[i]), int(obs.step[j])))
    pair_az = np.array(pair_az)
    if not two_axis:
        warnings.append(f"{where}: one level gyro axis: eq. 4.3 leaves a ±180° ambiguity (psi or -psi); "
                        "every pair is put on the first pair's branch")
        # each pair gives +-psi about its home angle; align all to the first pair's branch
        home = ang[0:2 * n_pairs:2]
        cand = np.stack([pair_az, angle_diff(-(pair_az + home), home)])
        ref = cand[0, 0]
        pick = np.argmin(np.abs(angle_diff(cand, ref)), axis=0)
        pair_az = cand[pick, np.arange(n_pairs)]
    mean = circular_mean(pair_az)
    dev = angle_diff(pair_az, mean)
    std = float(np.std(dev, ddof=1)) if n_pairs > 1 else np.nan
    fit = fit_harmonic(obs.subset(np.arange(2 * n_pairs)), geom, latitude, drift=drift and n_pairs > 1, where=where)
    sigma = std / np.sqrt(n_pairs) if n_pairs >= 3 else fit.azimuth_sigma
    return MaytagResult(pair_az, np.array(pair_t), np.array(pair_steps), np.array(pair_amp), mean, float(sigma), std,
                        fit, not two_axis, tuple(warnings))


# -- redundant configuration (sec. 4.4.3) -------------------------------------------------

@dataclass(frozen=True)
class RedundantResult:
    """Simulated skewed four-axis configurations from consecutive 45° positions (sec. 4.4.3).

    ``pairings`` (K,) labels like ``"0-45"``; ``azimuth`` (T, K) rad, azimuth of body x at the
    table's zero from pairing k of turn t; ``turn_time`` (T,) s; ``bias`` (3,) rad/s the bias
    removed and ``bias_source``; ``mean`` (K,) rad per pairing; ``std`` (K,) rad over turns.
    """

    pairings: tuple[str, ...]
    azimuth: np.ndarray
    turn_time: np.ndarray
    bias: np.ndarray
    bias_source: str
    mean: np.ndarray
    std: np.ndarray


def redundant(obs: Observations, geom: AxisGeometry, latitude: float, positions_per_turn: int = 8,
              bias: np.ndarray | None = None, angle_tol: float = np.radians(0.5),
              where: str = "redundant") -> RedundantResult:
    """Azimuths of the eight pairings (0°-45°, ..., 315°-0°) of every turn (thesis sec. 4.4.3).

    Rows in time order form turns of ``positions_per_turn`` equally spaced angles. Each
    pairing combines the x and y outputs of positions k and k+1 of the same turn (315° pairs
    with that turn's 0°) into four readings on axes psi, psi+45°, psi+90°, psi+135° and solves
    (Omega_N cos psi, Omega_N sin psi) by least squares after removing the bias: ``bias``
    (3,) rad/s if given (a calibration), else the per-axis mean over all complete turns
    (the Earth rate averages out over equally spaced positions). Angles rad.
    """
    check_latitude(latitude, where)
    obs = obs.subset(np.argsort(obs.t))
    n_turns = len(obs) // positions_per_turn
    if n_turns < 1:
        raise AnalysisError(f"{where}: {len(obs)} positions; a turn needs {positions_per_turn}")
    obs = obs.subset(np.arange(n_turns * positions_per_turn))
    ang = obs.angle.reshape(n_turns, positions_per_turn)
    step = 2 * np.pi / positions_per_turn
    for t in range(n_turns):
        gaps = angle_diff(ang[t, 1:], ang[t, :-1])
        bad = np.abs(np.abs(gaps) - step) > angle_tol
        if bad.any():
            k = int(np.argmax(bad))
            s0, s1 = obs.step[t * positions_per_turn + k], obs.step[t * positions_per_turn + k + 1]
            raise AnalysisError(f"{where}: steps {s0} -> {s1}: index {np.degrees(gaps[k]):.3f}° is not "
                                f"{np.degrees(step):.1f}°")
    if bias is None:
        est = obs.rate.mean(axis=0) + geom.down * EARTH_RATE * np.sin(latitude)
        source = f"mean over {n_turns} complete turn(s)"
    else:
        est, source = np.asarray(bias, float), "given"
    labels = []
    az = np.zeros((n_turns, positions_per_turn))
    for k in range(positions_per_turn):
        k2 = (k + 1) % positions_per_turn
        a0 = np.degrees(ang[0, k]) % 360
        labels.append(f"{a0:.0f}-{(a0 + np.degrees(step)) % 360:.0f}")
        for t in range(n_turns):
            rows = np.array([t * positions_per_turn + k, t * positions_per_turn + k2])
            az[t, k] = fit_harmonic(obs.subset(rows), geom, latitude, bias=est, where=f"{where} turn {t}").azimuth
    mean = np.array([circular_mean(az[:, k]) for k in range(positions_per_turn)])
    std = np.array([np.std(angle_diff(az[:, k], mean[k]), ddof=1) if n_turns > 1 else np.nan
                    for k in range(positions_per_turn)])
    turn_time = obs.t.reshape(n_turns, positions_per_turn).mean(axis=1)
    return RedundantResult(tuple(labels), az, turn_time, est, source, mean, std)


# -- repeatability ------------------------------------------

def repeatability(means: np.ndarray) -> tuple[float, np.ndarray]:
    """Thesis repeatability of sequence means (rad): max |mean_j - grand mean| and each distance.

    ``means`` (J,) rad, the mean azimuth of each sequence (tables 4.3, 4.4; Fig. 4.14-4.23).
    """
    means = np.asarray(means, float)
    dist = angle_diff(means, circular_mean(means))
    return float(np.max(np.abs(dist))), dist


# -- a whole session ----------------------------------------------------------------------

METHODS = ("maytagging", "multiposition", "carousel", "redundant")


@dataclass(frozen=True)
class NoiseTerms:
    """Gyro noise terms per body axis, SI, for the theoretical figures, and where they come from.

    ``arw`` (3,) rad/√s, ``bias_instability`` (3,) rad/s (IEEE 952 B), ``rrw`` (3,) rad/s/√s,
    ``quantization`` (3,) rad; ``source`` e.g. ``"grade cvg_two_axis"``.
    """

    arw: np.ndarray
    bias_instability: np.ndarray
    rrw: np.ndarray
    quantization: np.ndarray
    source: str

    @classmethod
    def from_spec(cls, spec) -> NoiseTerms:
        """From a grade (``workbench.grades.SensorSpec``) gyro noise."""
        nz = spec.specs["gyro"].noise
        return cls(nz.white, nz.bias_instability, nz.rrw, nz.quantization, f"grade {spec.name}")


@dataclass(frozen=True)
class NorthFinding:
    """North-finding result of one session (all SI; see :func:`find_north`).

    ``azimuth`` rad of body x at the table's zero, clockwise from true north, and its 1-sigma
    ``azimuth_sigma`` (std of the units / sqrt(count) with 3 or more units, else formal);
    ``units`` (pairs, turns, laps, or pairing estimates) with ``unit_azimuth`` (U,) rad,
    ``unit_time`` (U,) s and ``unit_std`` rad; ``gyro_bias`` (3,) rad/s with ``gyro_bias_sigma``
    (NaN: not observed); ``earth_rate_amplitude`` rad/s (NaN: not observed with one axis) against
    ``expected_amplitude = Omega_e cos lat``; ``averaging_time`` s of one row (mean);
    ``theory`` rad: ``arw_unit_sigma``, ``allan_unit_sigma``, with ``adev_at_dwell`` (3,) rad/s
    and ``source``; ``true_azimuth`` rad when the session knows the table's zero azimuth.
    """

    method: str
    units: str
    azimuth: float
    azimuth_sigma: float
    unit_azimuth: np.ndarray
    unit_time: np.ndarray
    unit_std: float
    gyro_bias: np.ndarray
    gyro_bias_sigma: np.ndarray
    earth_rate_amplitude: float
    earth_rate_amplitude_sigma: float
    expected_amplitude: float
    latitude: float
    averaging_time: float
    theory: dict
    true_azimuth: float | None
    obs: Observations
    geometry: AxisGeometry
    fit: HarmonicFit
    detail: MaytagResult | RedundantResult | None
    ambiguous: bool
    warnings: tuple[str, ...]

    @property
    def azimuth_error(self) -> float | None:
        """Estimated minus true azimuth, rad (None when the table's zero azimuth is unknown)."""
        return None if self.true_azimuth is None else float(angle_diff(self.azimuth, self.true_azimuth))


def _session_mount(session: Session, obs: Observations, max_tilt: float, axes: Sequence[int]) -> AxisGeometry:
    """The one mount of the rows' steps, checked level for the sensing ``axes`` (AnalysisError naming the step)."""
    mounts = [session.step(int(i)).mount for i in np.unique(obs.step)]
    for i, m in zip(np.unique(obs.step), mounts):
        if not np.allclose(m, mounts[0], atol=1e-9):
            raise AnalysisError(f"{session.name}: step {i}: mount differs from step {obs.step[0]}'s; "
                                "north-finding needs one mount")
    return AxisGeometry.from_mount(mounts[0], max_tilt, f"{session.name}: step {int(obs.step[0])} mount", axes)


def _accel_tilt_warning(session: Session, steps: np.ndarray, geom: AxisGeometry, max_tilt: float) -> list[str]:
    """Warn when the accelerometers show a level gyro axis tilted beyond ``max_tilt`` (rad)."""
    data = _Samples(session)
    cuts = [data.cut(st, 0.0, static=st.kind == "static") for st in (session.step(int(i)) for i in np.unique(steps))]
    f = np.mean([c["accel"].mean(axis=0) for c in cuts], axis=0)
    tilt = np.arcsin(np.clip(np.abs(f) / np.linalg.norm(f), 0.0, 1.0))
    bad = [i for i in np.flatnonzero(geom.horizontal) if tilt[i] > max_tilt]
    return [f"{session.name}: accelerometers show body {'xyz'[i]} tilted {np.degrees(tilt[i]):.2f}° from level "
            f"(limit {np.degrees(max_tilt):.2f}°): the table or the fixture is not level" for i in bad]


def earth_rate_free_series(session: Session, obs: Observations, fit: HarmonicFit, geom: AxisGeometry,
                           settle_s: float) -> np.ndarray:
    """Gyro samples (N, 3) rad/s of the rows' steps with the fitted Earth rate and table rate removed.

    Static and rotating steps alike (each sample at its own table angle), after ``settle_s``,
    concatenated in time order: the bias + noise series the Allan deviation is taken on
    (the index moves between steps are skipped, so the record is treated as contiguous).
    """
    lat = session.site.latitude
    data = _Samples(session)
    parts = []
    for idx in np.unique(obs.step):
        st = session.step(int(idx))
        c = data.cut(st, settle_s, static=st.kind == "static")
        model = fit.model(c["angle"], geom, lat) - fit.bias + geom.down * c["rate"][:, None]
        parts.append(c["gyro"] - model)
    return np.concatenate(parts)


def _data_adev(series: np.ndarray, rate_hz: float, tau: float, where: str) -> np.ndarray:
    """Overlapping ADEV (3,) rad/s at ``tau`` s of a series (workbench.analysis.allan)."""
    from workbench.analysis.allan import deviation

    if len(series) < 3 * tau * rate_hz:
        raise AnalysisError(f"{where}: {len(series) / rate_hz:.0f} s of data cannot give the Allan deviation "
                            f"at {tau:.0f} s")
    curve = deviation(series, rate_hz, "oadev", taus=np.array([tau]), source=where)
    return curve.dev[0]


def _theory(method: str, nf_parts: dict, noise: NoiseTerms | None, series_fn, session: Session,
            geom: AxisGeometry) -> dict:
    """Theoretical per-unit 1-sigma (rad) from ARW alone and from the ADEV at the unit's averaging time."""
    from workbench.analysis import northfinding_theory as th

    lat = session.site.latitude
    hz = np.flatnonzero(geom.horizontal)
    tau = nf_parts["tau"]
    if noise is not None:
        adev = th.adev_model(tau, noise.arw, noise.bias_instability, noise.rrw, noise.quantization)
        white = noise.arw / np.sqrt(tau)
        source = noise.source
    else:
        adev = _data_adev(series_fn(), session.sample_rate_hz, tau, session.name)
        white = np.full(3, np.nan)  # no ARW without a noise model: not observed
        source = f"data: overlapping ADEV at {tau:.1f} s of the Earth-rate-free series"
    out = {"source": source, "tau": float(tau), "adev_at_dwell": adev}
    for key, sig in (("arw_unit_sigma", white), ("allan_unit_sigma", adev)):
        if not np.all(np.isfinite(sig[hz])):
            out[key] = float("nan")
        elif method in ("maytagging", "redundant"):
            psi = nf_parts.get("home_azimuth")
            out[key] = (th.pair_azimuth_sigma(sig[hz[0]], lat, sig[hz[1]], psi) if len(hz) > 1
                        else th.pair_azimuth_sigma(sig[hz[0]], lat, None, psi))
        else:
            out[key] = th.harmonic_sigma(sig[hz] / geom.gain[hz], nf_parts["rows_per_unit"], lat)
    return out


def find_north(session: Session, method: str, settle_s: float = 2.0, drift: bool | None = None,
               index_tol_deg: float = 0.05, max_tilt_deg: float = 1.0, grade: SensorSpec | None = None,
               bias: np.ndarray | None = None, positions_per_turn: int | None = None,
               bin_deg: float = 5.0, axes: Sequence[int] | None = None, discard_s: float = 0.0) -> NorthFinding:
    """Find north from a session with ``method`` in :data:`METHODS`.

    * ``maytagging``: static steps paired in time order, 180° apart within ``index_tol_deg``;
    * ``multiposition``: static steps evenly spread round the turn (Earth-rate sweep), one
      fit per turn of ``positions_per_turn`` (default: the distinct angles) and one of all;
    * ``carousel``: the ``carousel`` steps binned by ``bin_deg``, one fit per lap and one of all;
    * ``redundant``: static 45° steps, the eight pairings of sec. 4.4.3 (``bias`` (3,) rad/s
      removes a known bias; default the turn mean).

    ``settle_s`` s dropped at the start of each step; ``drift`` fits a linear bias drift
    (default: off for maytagging, on otherwise); ``max_tilt_deg``: body x must be level and
    other axes level or vertical within it; ``grade``: the grade (a
    :class:`~workbench.grades.SensorSpec`, given by the caller: an analysis reads no fixture)
    whose noise terms give the theoretical figures (default: the session's own ADEV);
    ``axes``: the gyro's sensing axes (default: the grade's ``sensing_axes``, else all three);
    ``discard_s``: steps that start less than this after the session's first sample are left
    out (warm-up: thesis table 4.2, sequences 8-11 "extracted one hour after the starting").
    The azimuth never uses the site's ``table_zero_azimuth_deg``; when known it gives
    ``true_azimuth``.
    """
    from workbench.analysis.northfinding_theory import horizontal_rate

    if method not in METHODS:
        raise AnalysisError(f"{session.name}: unknown north-finding method {method!r} "
                            f"(expected one of {', '.join(METHODS)})")
    lat = session.site.latitude
    check_latitude(lat, f"{session.name}: site.latitude_deg")
    max_tilt = np.radians(max_tilt_deg)
    spec = grade
    drift = (method != "maytagging") if drift is None else bool(drift)
    where = f"{session.name}: {method}"
    if method == "carousel":
        obs = rotating_observations(session, settle_s, bin_deg)
    else:
        obs = static_observations(session, settle_s)
    obs = obs.subset(np.argsort(obs.t))
    if discard_s > 0:
        t0 = float(session.samples["t"].iloc[0])
        obs = obs.subset(np.array([session.step(int(i)).t_start - t0 >= discard_s for i in obs.step], bool))
        if len(obs) == 0:
            raise AnalysisError(f"{session.name}: {method}: no step starts after the {discard_s:g} s discarded "
                                "for warm-up")
    if axes is None:
        axes = spec.specs["gyro"].sensing_axes if spec is not None else (0, 1, 2)
    geom = _session_mount(session, obs, max_tilt, axes)
    warnings = _accel_tilt_warning(session, obs.step, geom, max_tilt)
    detail, ambiguous = None, False
    parts: dict = {"tau": float(np.mean(obs.duration))}

    if method == "maytagging":
        detail = maytag(obs, geom, lat, np.radians(index_tol_deg), drift, where)
        fit, ambiguous = detail.fit, detail.ambiguous
        unit_az, unit_t, azimuth = detail.pair_azimuth, detail.pair_time, detail.azimuth
        warnings += list(detail.warnings)
        parts["home_azimuth"] = float(azimuth + obs.angle[0])
        units = "pair"
    elif method == "redundant":
        per = positions_per_turn or 8
        detail = redundant(obs, geom, lat, per, bias, where=where)
        fit = fit_harmonic(obs, geom, lat, drift=drift, where=where)
        unit_az, unit_t = detail.azimuth.ravel(), np.repeat(detail.turn_time, len(detail.pairings))
        azimuth = circular_mean(unit_az)
        units = "pairing estimate"
    else:
        fit = fit_harmonic(obs, geom, lat, drift=drift, where=where)
        if method == "carousel":  # laps counted from each step's start
            rate = np.array([session.step(int(i)).table_rate for i in obs.step])
            t0 = np.array([session.step(int(i)).t_start for i in obs.step])
            groups = obs.step * 100000 + np.floor(np.abs(rate) * (obs.t - t0) / (2 * np.pi)).astype(int)
            units = "lap"
        else:
            n_angles = len(np.unique(np.round(np.mod(obs.angle, 2 * np.pi), 4)))
            per = positions_per_turn or n_angles
            groups = np.arange(len(obs)) // per
            units = "turn"
        labels, counts = np.unique(groups, return_counts=True)
        full = labels[counts >= 0.9 * counts.max()]  # complete turns / laps only (bins need not align with laps)
        keep = np.isin(groups, full)
        unit_az = group_fits(obs.subset(keep), groups[keep], geom, lat, where)
        unit_t = np.array([obs.t[groups == g].mean() for g in full])
        azimuth = fit.azimuth
        parts["rows_per_unit"] = int(counts.max())
        if method == "carousel":  # one lap is one row of its whole duration
            parts["tau"] = float(np.sum(obs.duration[groups == full[0]]))
            parts["rows_per_unit"] = 1
    n_units = len(unit_az)
    dev = angle_diff(unit_az, azimuth) if n_units else np.zeros(0)
    unit_std = float(np.std(dev, ddof=1)) if n_units > 1 else float("nan")
    az_sigma = unit_std / np.sqrt(n_units) if n_units >= 3 else fit.azimuth_sigma
    if method == "redundant":
        az_sigma = float(np.std([circular_mean(detail.azimuth[t]) for t in range(detail.azimuth.shape[0])],
                                ddof=1) / np.sqrt(detail.azimuth.shape[0])) if detail.azimuth.shape[0] >= 3 \
            else fit.azimuth_sigma
    amp, amp_sigma = (float("nan"), float("nan")) if ambiguous else (fit.amplitude, fit.amplitude_sigma)
    expected = horizontal_rate(lat)
    if np.isfinite(amp) and abs(amp / expected - 1.0) > max(0.05, 5 * amp_sigma / expected):
        warnings.append(f"{where}: fitted horizontal Earth rate {amp / expected:.4f} x Omega_e cos(lat): "
                        "a scale-factor error or a wrong site latitude")
    noise = NoiseTerms.from_spec(spec) if spec is not None and "gyro" in spec.specs else None
    theory = _theory(method, parts, noise,
                     lambda: earth_rate_free_series(session, obs, fit, geom, settle_s), session, geom)
    az0 = session.site.table_zero_azimuth
    true_az = None if az0 is None else float(angle_diff(az0 + geom.heading, 0.0))
    return NorthFinding(method, units, float(azimuth), float(az_sigma), np.asarray(unit_az), np.asarray(unit_t),
                        unit_std, fit.bias, fit.bias_sigma, amp, amp_sigma, expected, lat, float(np.mean(obs.duration)),
                        theory, true_az, obs, geom, fit, detail, ambiguous, tuple(warnings))



def _json_num(x) -> float | None | list:
    """JSON value of a float or array: NaN (not observed) becomes null."""
    arr = np.asarray(x, float)
    if arr.ndim:
        return [_json_num(v) for v in arr]
    return float(arr) if np.isfinite(arr) else None


def to_result(nf: NorthFinding) -> tuple[dict, list[str]]:
    """The ``result.json`` dict (keys name their lab unit; rad/s otherwise) and summary lines.

    Keys: ``azimuth_deg`` [0, 360), ``azimuth_sigma_mrad``, ``pair_azimuths_deg``,
    ``pair_times_s``, ``pair_std_mrad``, ``units``, ``gyro_bias`` (3,) rad/s and its sigma,
    ``earth_rate_amplitude`` rad/s with ``earth_rate_expected`` = Omega_e cos lat,
    ``theory`` {``arw_pair_sigma_mrad``, ``allan_pair_sigma_mrad``, ``source``,
    ``averaging_time_s``, ``adev_at_dwell``}, ``azimuth_error_mrad`` when the table's zero
    azimuth is known, ``redundant`` (per pairing) for that method.
    """
    from workbench.units import fmt

    th = nf.theory
    res = {
        "method": nf.method,
        "azimuth_deg": float(np.degrees(nf.azimuth) % 360.0),
        "azimuth_sigma_mrad": _json_num(nf.azimuth_sigma * 1e3),
        "units": nf.units,
        "pair_azimuths_deg": _json_num(np.degrees(nf.unit_azimuth) % 360.0),
        "pair_times_s": _json_num(nf.unit_time),
        "pair_std_mrad": _json_num(nf.unit_std * 1e3),
        "gyro_bias": _json_num(nf.gyro_bias),
        "gyro_bias_sigma": _json_num(nf.gyro_bias_sigma),
        "earth_rate_amplitude": _json_num(nf.earth_rate_amplitude),
        "earth_rate_amplitude_sigma": _json_num(nf.earth_rate_amplitude_sigma),
        "earth_rate_expected": nf.expected_amplitude,
        "latitude_deg": float(np.degrees(nf.latitude)),
        "one_axis_ambiguous": nf.ambiguous,
        "theory": {"arw_pair_sigma_mrad": _json_num(th["arw_unit_sigma"] * 1e3),
                   "allan_pair_sigma_mrad": _json_num(th["allan_unit_sigma"] * 1e3),
                   "source": th["source"], "averaging_time_s": th["tau"],
                   "adev_at_dwell": _json_num(th["adev_at_dwell"])},
    }
    if nf.azimuth_error is not None:
        res["azimuth_error_mrad"] = nf.azimuth_error * 1e3
    if isinstance(nf.detail, RedundantResult):
        d = nf.detail
        res["redundant"] = {"bias_source": d.bias_source, "pairings": [
            {"pairing_deg": lab, "mean_deg": float(np.degrees(m) % 360.0), "std_mrad": _json_num(s * 1e3),
             "n": int(d.azimuth.shape[0])} for lab, m, s in zip(d.pairings, d.mean, d.std)]}
    summary = [
        f"azimuth of body x at table zero: {res['azimuth_deg']:.4f}° ± {nf.azimuth_sigma * 1e3:.3g} mrad (1σ, "
        f"{len(nf.unit_azimuth)} {nf.units}s)",
        f"per-{nf.units} std: {nf.unit_std * 1e3:.3g} mrad; theory {th['arw_unit_sigma'] * 1e3:.3g} mrad (ARW only), "
        f"{th['allan_unit_sigma'] * 1e3:.3g} mrad (ADEV at {th['tau']:.0f} s; {th['source']})",
        f"horizontal Earth rate: {fmt(nf.earth_rate_amplitude, 'deg/h')} "
        f"(Ω_e cos lat = {fmt(nf.expected_amplitude, 'deg/h')})",
        "gyro bias: " + ", ".join(f"{a} {fmt(b, 'deg/h')}" for a, b in zip("xyz", nf.gyro_bias)),
    ]
    if nf.azimuth_error is not None:
        summary.append(f"error against the table's known zero azimuth: {nf.azimuth_error * 1e3:+.3g} mrad")
    if isinstance(nf.detail, RedundantResult):
        summary.append(f"redundant: bias {nf.detail.bias_source}; the theory is the noise floor with the bias known, "
                       "the spread adds the bias wander over the session (thesis: thermal drift)")
    if nf.ambiguous:
        summary.append("one level axis (eq. 4.3): the azimuth may be mirrored (psi or -psi about the pair's home)")
    return res, summary


def sequence_table(results: Sequence[NorthFinding], labels: Sequence[str] | None = None) -> list[dict]:
    """Rows of thesis table 4.3 over sessions: mean azimuth (°), per-unit std (mrad), distance of
    the mean from the mean of all (mrad, Fig. 4.14-4.15) and the session's 1-sigma (mrad)."""
    means = np.array([r.azimuth for r in results])
    _, dist = repeatability(means)
    labels = labels or [str(i + 1) for i in range(len(results))]
    return [{"sequence": lab, "mean_deg": float(np.degrees(r.azimuth)), "std_mrad": r.unit_std * 1e3,
             "distance_mrad": float(d * 1e3), "sigma_mrad": r.azimuth_sigma * 1e3}
            for lab, r, d in zip(labels, results, dist)]


def pairing_table(results: Sequence[NorthFinding]) -> list[dict]:
    """Rows of thesis table 4.4 over redundant sessions: per pairing, the repeatability (max
    distance of each session's pairing mean from the mean over sessions), mrad and degrees."""
    details = [r.detail for r in results]
    if not details or not all(isinstance(d, RedundantResult) for d in details):
        raise AnalysisError("pairing_table: needs redundant-configuration results")
    rows = []
    for k, lab in enumerate(details[0].pairings):
        rep, _ = repeatability(np.array([d.mean[k] for d in details]))
        rows.append({"pairing_deg": lab, "repeatability_mrad": rep * 1e3, "repeatability_deg": float(np.degrees(rep)),
                     "std_over_turns_mrad": float(np.sqrt(np.mean([d.std[k] ** 2 for d in details])) * 1e3)})
    return rows
