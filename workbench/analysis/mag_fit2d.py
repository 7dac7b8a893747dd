"""2D (level-plane) magnetometer calibration: paper 004 eq. 10-18 and its least-squares form.

With the unit level and turned about the vertical, the two horizontal magnetometer axes
trace an ellipse: centre = hard iron (plus the constant coupling of the vertical field
through the soft iron), shape = the 2x2 soft iron. Paper 004 (shared/seeds/004_...):

- eq. 10-11: offsets ``alpha = (x_max + x_min)/2``, ``beta = (y_max + y_min)/2``;
- eq. 12-13: ``r = |p1|``, ``theta = asin(y1 / r)`` for the point ``p1`` farthest from the centre
  (the major-axis direction);
- eq. 14-15: rotate by ``R(theta)`` so the major axis lies along x;
- eq. 16-18: scale x by ``1/sigma``, ``sigma`` = major / minor axis, and rotate back.

:func:`fit_2d_minmax` is that recipe verbatim (extremes of the data, so noise biases it);
:func:`fit_2d` estimates the same quantities (``alpha, beta, theta, sigma``) by least squares on
all points, with uncertainties. Both return a :class:`MagFit` embedded in 3D: the vertical
axis's bias, the soft-iron row and column of the vertical axis and the field norm are NOT
observable from level data (NaN sigma, prior values: bias 0, identity), and say so; nor is the common
scale of the 2x2 block (it trades with the horizontal field ``H``): the convention fixes the minor axis
at 1, so the diagonal element nearest the minor axis carries the convention, not data (NaN sigma).
"""

from __future__ import annotations

import numpy as np

from workbench.analysis.mag_fit import MagFit, Solution, nan33, propagate, solve
from workbench.errors import AnalysisError

NOT_OBSERVABLE = ("level-only data: the vertical axis's hard iron, the soft iron coupling to it, the dip, the "
                  "field norm and the common scale of the horizontal soft iron (the paper's convention sets the minor "
                  "axis to 1: that diagonal element reads not observed) are not observable (sigma null); 2D "
                  "calibration valid for level headings only")


def _rot(theta: float) -> np.ndarray:
    """Paper 004 eq. 14: R = [[cos, sin], [-sin, cos]]."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, s], [-s, c]])


def soft_iron_2d(theta: float, sigma: float) -> np.ndarray:
    """The 2x2 distortion ``A2`` that eq. 14-18 undo: ``A2 = R^T diag(sigma, 1) R`` (``m = A2 h + offset``)."""
    r = _rot(theta)
    return r.T @ np.diag([sigma, 1.0]) @ r


def _plane_axes(down_mean: np.ndarray) -> tuple[int, int, int]:
    """(horizontal axis 1, horizontal axis 2, vertical axis) of the body frame for level data."""
    v = int(np.argmax(np.abs(down_mean)))
    h = [i for i in range(3) if i != v]
    return h[0], h[1], v


def _embed(method: str, xy_axes: tuple[int, int, int], offset, offset_sig, a2, a2_sig, h_norm, mag, rms, n,
           warnings, rejected: np.ndarray | None = None) -> MagFit:
    i, j, v = xy_axes
    b, sb = np.zeros(3), np.full(3, np.nan)
    b[[i, j]], sb[[i, j]] = offset, offset_sig
    a, sa = np.eye(3), nan33()
    a[np.ix_([i, j], [i, j])] = a2
    sa[np.ix_([i, j], [i, j])] = a2_sig
    vert = float(np.mean(mag[:, v]))
    norm = float(np.hypot(h_norm, vert))  # assumes the unobserved vertical hard iron is zero (prior)
    return MagFit(method, b, sb, a, sa, norm, float("nan"), rms, n, "2d: minor axis = horizontal field",
                  warnings=(*warnings, NOT_OBSERVABLE),
                  rejected=() if rejected is None else tuple(int(i) for i in np.flatnonzero(rejected)))


def fit_2d_minmax(mag: np.ndarray, down_mean: np.ndarray = np.array([0.0, 0.0, 1.0]),
                  robust: bool | str = False) -> MagFit:
    """Paper 004 eq. 10-18 verbatim on level data (N, 3) µT; no uncertainty (NaN sigma).

    ``down_mean`` (3,) body-frame down direction, picks the vertical axis (z for a level unit).
    ``robust`` (True or ``"auto"``): the extremes are taken over the points a robust least-squares
    2D fit (:func:`fit_2d`) keeps, since one spike sets a minimum or maximum on its own.
    """
    axes = _plane_axes(down_mean)
    rejected = np.zeros(len(mag), bool)
    if robust:
        rejected[list(fit_2d(mag, down_mean, robust).rejected)] = True
    notes = ("paper 004 min/max recipe: no uncertainty estimated",)
    if rejected.any():
        notes += (f"robust: {int(rejected.sum())} of {len(mag)} points rejected as outliers before the min/max",)
    xy = mag[~rejected][:, axes[:2]]
    off = 0.5 * (xy.max(axis=0) + xy.min(axis=0))  # eq. 10-11
    p = xy - off
    k = int(np.argmax(np.sum(p**2, axis=1)))
    r = float(np.hypot(*p[k]))  # eq. 12
    theta = float(np.arcsin(p[k, 1] / r))  # eq. 13
    if p[k, 0] < 0:
        theta = -theta  # the major axis through p1 or -p1 (asin alone cannot tell)
    q = p @ _rot(theta).T  # eq. 15
    sigma = float(np.abs(q[:, 0]).max() / np.abs(q[:, 1]).max())  # eq. 16: major / minor
    a2 = soft_iron_2d(theta, sigma)
    h = p @ np.linalg.inv(a2).T
    hn = float(np.abs(q[:, 1]).max())
    rms = float(np.sqrt(np.mean((np.linalg.norm(h, axis=1) - hn) ** 2)))
    return _embed("2d-minmax", axes, off, np.full(2, np.nan), a2, np.full((2, 2), np.nan), hn, mag, rms, len(xy),
                  notes, rejected)


def fit_2d(mag: np.ndarray, down_mean: np.ndarray = np.array([0.0, 0.0, 1.0]),
           robust: bool | str = False) -> MagFit:
    """Least-squares 2D calibration of level data (N, 3) µT: offsets, ``theta``, ``sigma`` of paper 004 with sigmas.

    Fits ``|diag(1/sigma, 1) R(theta) (m_xy - offset)| = H`` (``H`` the horizontal field, µT,
    the minor semi-axis as in the paper's scaling) by least squares on all points.
    """
    axes = _plane_axes(down_mean)
    xy = mag[:, axes[:2]]
    if len(xy) < 6:
        raise AnalysisError(f"2D fit: {len(xy)} points, need at least 6")
    c0 = xy.mean(axis=0)
    ev, evec = np.linalg.eigh(np.cov((xy - c0).T))
    if ev[0] <= 0:
        raise AnalysisError("2D fit: the horizontal points are collinear (did the table turn?)")
    theta0 = float(np.arctan2(evec[1, 1], evec[0, 1]))
    p0 = np.array([*c0, theta0, np.sqrt(ev[1] / ev[0]), np.sqrt(2 * ev[0])])

    def resid(p, idx):
        q = (xy[idx] - p[:2]) @ _rot(p[2]).T
        return (np.hypot(q[:, 0] / p[3], q[:, 1]) - p[4])[:, None]

    sol: Solution = solve(resid, p0, len(xy), robust)
    p = sol.p.copy()
    if p[3] < 1.0:  # same ellipse described from the other axis: keep sigma = major / minor >= 1
        p = np.array([p[0], p[1], p[2] + np.pi / 2, 1.0 / p[3], p[4] * p[3]])
        sol = solve(resid, p, len(xy), robust)
        p = sol.p
    p[2] = (p[2] + np.pi / 2) % np.pi - np.pi / 2

    def a2_of(q):
        return soft_iron_2d(q[2], q[3]).ravel()

    cov_a2 = propagate(a2_of, p, sol.cov)
    sig = np.sqrt(np.abs(np.diag(sol.cov)))
    notes = []
    if robust and (~sol.inliers).any():
        notes.append(f"robust fit: {int((~sol.inliers).sum())} of {len(xy)} points rejected as outliers")
    rms = float(np.sqrt(np.mean(sol.residuals**2)))
    a2_sig = np.sqrt(np.abs(np.diag(cov_a2))).reshape(2, 2)
    a2_sig[_minor_diagonal(p[2]), _minor_diagonal(p[2])] = np.nan  # the convention's, not the data's (see NOT_OBSERVABLE)
    return _embed("2d", axes, p[:2], sig[:2], a2_of(p).reshape(2, 2), a2_sig,
                  float(p[4]), mag, rms, int(sol.inliers.sum()), tuple(notes), ~sol.inliers)


def _minor_diagonal(theta: float) -> int:
    """Index (0 or 1, of the two horizontal axes) of the diagonal element of ``A2 = R^T diag(sigma, 1) R`` nearest
    the minor axis ``(-sin theta, cos theta)``: the element the scaling convention (minor axis = 1) sets."""
    return 1 if abs(np.cos(theta)) >= abs(np.sin(theta)) else 0
