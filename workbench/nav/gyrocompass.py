"""Coarse heading from the Earth rate: the gyrocompass, at one position or through a table's holds (closed form).

One position (paper 001 eq. 48): the horizontal Earth rate ``Omega cos(lat)`` points north, so the heading
of the body x axis is ``atan2(-w_y, w_x)`` of the mean gyro output rotated into the levelled frame; a
horizontal gyro bias ``b`` moves it by ``b / (Omega cos(lat))`` and cannot be told apart from it.

Through holds (the indexed, or multi-position, gyrocompass): the table turns the unit about the vertical
between holds, so the body bias turns in the level frame while the Earth rate stays north. In hold ``k``,
levelled with its own accelerometer mean and turned by ``theta_k`` from the first hold (the gyros integrated
through the turns), the level-frame horizontal rate is

    w_k = M(theta_k) u + (L_k b)[:2] + n_k,    u = Omega cos(lat) (cos psi_0, -sin psi_0),
    M(theta) = [[cos theta, sin theta], [-sin theta, cos theta]],

linear in ``u`` (2) and the body bias ``b`` (3, with its prior): weighted least squares, then
``psi_0 = atan2(-u_y, u_x)``. With one hold it is the one-position gyrocompass. The ZUPT alignment
linearises its error model at this heading (:mod:`workbench.nav.zupt`): it is closed form, uses the whole
record, and through turns is good to about the white-noise limit ``ARW / (Omega cos(lat) sqrt(T))``.

Public: :func:`gyrocompass`, :class:`CoarseHeading`, :func:`indexed_gyrocompass`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from workbench.earth import earth_rate_ned
from workbench.errors import AnalysisError
from workbench.nav.strapdown import BlockPropagator, coarse_level, euler_rph, from_rph

MIN_HOLD_S = 1.0  # s: still runs shorter than this (the edges of a turn) are not levelled on


def gyrocompass(rate_level: np.ndarray, latitude: float) -> float:
    """Heading rad of the body x axis from the mean gyro output rotated into the levelled frame (3,) rad/s.

    ``psi = atan2(-w_y, w_x)`` of the level-frame rate (paper 001 eq. 48). A gyro bias b moves it by
    ``b_h / (Omega cos(lat))``.
    """
    del latitude  # the direction does not depend on it; the sensitivity does (see the docstring)
    return float(np.arctan2(-rate_level[1], rate_level[0]))


@dataclass(frozen=True)
class CoarseHeading:
    """Closed-form heading of the body x axis at the first hold, rad, with its linearised 1-sigma (rad) and the
    number of holds it used."""

    heading: float
    sigma: float
    holds: int


def _still_runs(still: np.ndarray, min_len: int) -> list[tuple[int, int]]:
    """(start, stop) sample indices of the runs of True in ``still`` at least ``min_len`` long."""
    edges = np.diff(np.concatenate([[0], still.astype(np.int8), [0]]))
    runs = zip(np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0])
    return [(int(a), int(b)) for a, b in runs if b - a >= min_len]


def indexed_gyrocompass(gyro: np.ndarray, accel: np.ndarray, still: np.ndarray, dt: float, latitude: float,
                        gyro_white: np.ndarray, gyro_bias_prior: np.ndarray) -> CoarseHeading:
    """Heading of the body x axis at the first hold from the holds' mean rates (module docstring).

    ``gyro`` (N, 3) rad/s and ``accel`` (N, 3) m/s² body-frame samples at ``dt`` s; ``still`` (N,) bool the
    samples at which the table stands (turns about the vertical in between); ``latitude`` rad;
    ``gyro_white`` (3,) rad/√s white-noise density; ``gyro_bias_prior`` (3,) rad/s 1-sigma of the body bias.
    The turn angles come from the gyros integrated through the turns (Earth rate removed; the bias over a
    turn of seconds is negligible here).
    """
    runs = _still_runs(np.asarray(still, bool), max(1, int(round(MIN_HOLD_S / dt))))
    if not runs:
        raise AnalysisError(f"gyrocompass: no still run of {MIN_HOLD_S:g} s to level on")
    w_ie = earth_rate_ned(latitude)
    q = np.diag(np.asarray(gyro_white, float) ** 2)
    rows, rates, infos = [], [], []
    c_prev, theta = None, 0.0  # theta: the heading turned from the first hold, rad
    for a, b in runs:
        roll, pitch = coarse_level(accel[a:b])
        if c_prev is not None:  # through the turn from the previous hold's last sample to this hold's first
            c_end = BlockPropagator(a - c_prev[1], dt, w_ie).propagate(c_prev[0], gyro[c_prev[1]:a + 1])[-1]
            theta = float(euler_rph(Rotation.from_matrix(c_end))[2])
        lvl = from_rph(roll, pitch, 0.0).as_matrix()  # body to the hold's level frame (heading 0)
        m = np.array([[np.cos(theta), np.sin(theta)], [-np.sin(theta), np.cos(theta)]])
        rows.append(np.hstack([m, lvl[:2]]))
        rates.append((lvl @ gyro[a:b].mean(axis=0))[:2])
        infos.append(np.linalg.inv((lvl @ q @ lvl.T)[:2, :2] / ((b - a) * dt)))
        c_prev = (from_rph(roll, pitch, theta).as_matrix(), b - 1)
    info = np.zeros((5, 5))
    info[2:, 2:] = np.diag(np.asarray(gyro_bias_prior, float) ** -2.0)
    rhs = np.zeros(5)
    for h, w, i in zip(rows, rates, infos):
        info += h.T @ i @ h
        rhs += h.T @ i @ w
    cov = np.linalg.inv(info)
    x = cov @ rhs
    u = x[:2]
    jac = np.array([u[1], -u[0]]) / (u @ u)  # d atan2(-u_y, u_x) / du
    return CoarseHeading(float(np.arctan2(-u[1], u[0])), float(np.sqrt(jac @ cov[:2, :2] @ jac)), len(runs))
