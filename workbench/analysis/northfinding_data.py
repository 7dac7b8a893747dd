"""North-finding data: the observations (one row per static step or angle bin) and the axis geometry.

:class:`Observations` (table angle, time, gyro rate per row), :func:`static_observations`,
:func:`rotating_observations` (carousel bins), :class:`AxisGeometry` (which body axes are
level, their gain and direction in the table-top frame), :func:`circular_mean`,
:data:`STATIC_RATE_TOL`. Frames and references: :mod:`workbench.analysis.northfinding`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from workbench.angles import angle_diff, circular_mean  # noqa: F401  (re-exported)
from workbench.errors import AnalysisError
from workbench.session import Session


STATIC_RATE_TOL = 1e-9  # rad/s: |table_rate| below this counts as static


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


def _settled_cuts(session: Session, chosen, settle_s: float, static: bool):
    """(step, cut, where) for each chosen step after its first ``settle_s`` seconds; AnalysisError naming
    the step when nothing is left (a static dwell, or a rotation's duration, not longer than ``settle_s``)."""
    data = _Samples(session)
    for st in chosen:
        c = data.cut(st, settle_s, static=static)
        if static:
            where = f"{session.name}: step {st.index} ({st.kind}{', ' + st.label if st.label else ''})"
        else:
            where = f"{session.name}: step {st.index} ({st.kind})"
        if c["span"] <= settle_s or len(c["t"]) == 0:
            what = "static dwell" if static else "duration"
            raise AnalysisError(f"{where}: {what} {c['span']:.3g} s is not longer than the settling time {settle_s:g} s")
        yield st, c, where


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
    rows = []
    for st, c, _ in _settled_cuts(session, chosen, settle_s, static=True):
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
    parts = []
    for st, c, where in _settled_cuts(session, chosen, settle_s, static=False):
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
