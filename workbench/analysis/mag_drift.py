"""A hard iron that moves through a record, with temperature or with time: fitted on one part of a hand-held
record, judged on another part or on other records of the unit.

A calibration stores one hard iron. A hand-held fit whose field norm is worse held out than in sample
(:mod:`workbench.analysis.mag_holdout`) may see a hard iron that follows the unit's temperature (an AMR
sensor's bridge offset drifts with it; a board warms after power-on) or one that moves with time for another
reason (the hand, a cable, the place the unit is held). :func:`fit_moving` fits

    ``|L (m - b0 - k x)| = 1``

to raw points ``m`` (µT, magnetometer axes) with one regressor ``x`` per point (a temperature offset °C, or a
time s): ``L`` symmetric, the inverse of ``F (I + M)`` (1/µT, ``F`` the field norm), ``b0`` the hard iron at
``x = 0`` (µT), ``k`` its rate (µT per unit of ``x``). Within one record a slow warm-up and any slow drift in
time are nearly the same regressor, so ``k`` is a temperature coefficient only if it also predicts records of
the unit at other temperatures (:func:`norm_errors` on them).

The die temperature of a MEMS IMU is often quantised coarsely (the MARG recordings: 0.094 °C steps, a few
levels per record); :func:`smoothed_temperature` averages it over a window, so the fraction of time at each
level (dithered by the noise) gives the slow temperature.

Public: :class:`MovingHardIron`, :func:`fit_moving`, :func:`smoothed_temperature`, :func:`norm_errors`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.optimize import least_squares

from workbench.analysis.effective_n import ess_scale
from workbench.analysis.mag_fit import MagFit
from workbench.errors import AnalysisError

_IU = np.triu_indices(3)


@dataclass(frozen=True)
class MovingHardIron:
    """``|inverse (m - bias - rate x)| = 1`` (see the module docstring): ``inverse`` (3, 3) 1/µT symmetric,
    ``bias`` (3,) µT at ``x = 0``, ``rate`` (3,) µT per unit of ``x`` with its 1-sigma ``rate_sigma`` (Gauss-Newton,
    scaled by the residuals' rms and correlation time), ``rms`` the in-sample relative norm residual, ``n`` points."""

    inverse: np.ndarray
    bias: np.ndarray
    rate: np.ndarray
    rate_sigma: np.ndarray
    rms: float
    n: int

    def compensate(self, mag: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Calibrated field (N, 3) in units of the fitted norm for raw ``mag`` (N, 3) µT at regressor ``x`` (N,)."""
        return (np.asarray(mag, float) - self.bias - np.outer(x, self.rate)) @ self.inverse.T


def _unpack(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    lm = np.zeros((3, 3))
    lm[_IU] = p[:6]
    return lm + np.triu(lm, 1).T, p[6:9], p[9:12]


def fit_moving(mag: np.ndarray, x: np.ndarray, start: MagFit) -> MovingHardIron:
    """Fit :class:`MovingHardIron` to raw points ``mag`` (N, 3) µT with regressor ``x`` (N,), started from a
    constant calibration ``start`` (its hard iron, soft iron and field norm). Raises AnalysisError when ``x``
    does not vary or the fit does not converge."""
    mag, x = np.asarray(mag, float), np.asarray(x, float)
    if len(mag) != len(x) or len(mag) < 13:
        raise AnalysisError(f"moving hard iron: {len(mag)} points and {len(x)} regressor values (need >= 13, equal)")
    if not np.ptp(x) > 0:
        raise AnalysisError("moving hard iron: the regressor does not vary over the points")
    lin = np.linalg.inv(start.field_norm_ut * start.soft_iron)
    p0 = np.concatenate([lin[_IU], start.bias, np.zeros(3)])

    def resid(p):
        lm, b, k = _unpack(p)
        return np.linalg.norm((mag - b - np.outer(x, k)) @ lm.T, axis=1) - 1.0

    sol = least_squares(resid, p0, x_scale="jac")
    if not sol.success:
        raise AnalysisError(f"moving hard iron: least squares did not converge ({sol.message})")
    r = sol.fun
    cov = np.linalg.pinv(sol.jac.T @ sol.jac) * np.mean(r**2) * float(ess_scale(r)) ** 2
    lm, b, k = _unpack(sol.x)
    return MovingHardIron(lm, b, k, np.sqrt(np.diag(cov)[9:12]), float(np.sqrt(np.mean(r**2))), len(mag))


def norm_errors(model: MovingHardIron, mag: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Calibrated field norm relative to the fitted one, minus 1 (N,), for raw ``mag`` (N, 3) µT at ``x`` (N,)."""
    return np.linalg.norm(model.compensate(mag, x), axis=1) - 1.0


def smoothed_temperature(t: np.ndarray, temp_c: np.ndarray, window_s: float) -> np.ndarray:
    """Temperature (N,) °C averaged over a centred ``window_s`` running window of samples at times ``t`` (N,) s
    (uniform sampling assumed; edges use the nearest value): a coarsely quantised die temperature becomes the
    slow temperature its dithering encodes."""
    t, temp_c = np.asarray(t, float), np.asarray(temp_c, float)
    if len(t) < 2:
        return temp_c.copy()
    n = max(1, int(round(window_s / float(np.median(np.diff(t))))))
    return uniform_filter1d(temp_c, n, mode="nearest")
