"""What the gyro noise does to the redundant configuration's pairing estimates, bias wander included.

The redundant method (thesis sec. 4.4.3, :func:`workbench.analysis.northfinding_fit.redundant`)
removes one bias per axis, the mean over the whole session, from every position. Its noise
floor (``pair_azimuth_sigma``, the ADEV at the dwell) holds only with the bias known; with the
session mean removed, flicker and rate random walk make each position's bias differ from the
session mean by what the noise wandered in between: the turns spread more than the floor
(thesis: "thermal drift"). This module propagates the IEEE 952 noise of each level gyro through
the estimator: the azimuth of each (turn, pairing) is linearised in the position means (the
two-position least squares, unweighted as the estimator is), the session-mean bias is chained in, and the generalised covariance of the position means
(:func:`workbench.allan_model.window_mean_covariance`) gives, per pairing, the expected std over
turns and the sigma of the session's pairing mean (both contrasts of the means, so flicker and
random walk have finite answers). Units: rad, rad/s, s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.allan_model import window_mean_covariance
from workbench.analysis.northfinding_data import AxisGeometry, Observations
from workbench.analysis.northfinding_fit import harmonic_design
from workbench.analysis.northfinding_theory import horizontal_rate

@dataclass(frozen=True)
class PairingSpread:
    """Per pairing (K,): ``turn_std`` rad, the expected std of its azimuths over the turns;
    ``mean_sigma`` rad, the sigma of the session's pairing mean (NaN with the bias given: not a
    contrast of the means, the calibration's own bias error decides it)."""

    turn_std: np.ndarray
    mean_sigma: np.ndarray


def _gradient(obs: Observations, rows: np.ndarray, geom: AxisGeometry, latitude: float, azimuth: float,
              weight: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """d azimuth / d rate (2, A) of the two-position least-squares estimate of ``rows`` (rad per rad/s).

    The estimate solves ``(Omega_N cos psi, Omega_N sin psi)`` from the level axes' readings
    (:func:`harmonic_design`) weighted per axis by ``weight`` (A,); linearised at ``azimuth``.
    """
    sub = obs.subset(rows)
    design = np.vstack([harmonic_design(sub, geom, a) for a in axes])  # (2 A, 2), rows axis-major
    w = np.repeat(weight, len(rows))
    gain = np.linalg.solve((design * w[:, None]).T @ design, (design * w[:, None]).T)  # (2, 2 A)
    jac = np.array([-np.sin(azimuth), np.cos(azimuth)]) / horizontal_rate(latitude)  # d atan2(s, c)
    return (jac @ gain).reshape(len(axes), len(rows)).T


def redundant_spread(obs: Observations, geom: AxisGeometry, latitude: float, positions_per_turn: int,
                     azimuth: np.ndarray, bias_known: bool, noise: dict[str, np.ndarray]) -> PairingSpread:
    """Expected spread of the redundant pairings of ``obs`` (rows in time order, whole turns).

    ``azimuth`` (K,) rad, each pairing's mean (where the estimate is linearised); ``bias_known``:
    False when the bias removed is the session mean (then chained in); ``noise`` the per-axis
    IEEE 952 terms ``arw``, ``bias_instability``, ``rrw``, ``quantization`` (3,) SI. The two
    positions' readings are unweighted, as :func:`fit_harmonic` leaves them with one residual per axis.
    """
    n_turns = len(obs) // positions_per_turn
    n = n_turns * positions_per_turn
    axes = np.flatnonzero(geom.horizontal)
    terms = [(noise["arw"][a], noise["bias_instability"][a], noise["rrw"][a], noise["quantization"][a]) for a in axes]
    start, end = obs.t[:n] - obs.duration[:n] / 2, obs.t[:n] + obs.duration[:n] / 2
    cov = [window_mean_covariance(start, end, *tm) for tm in terms]
    weight = np.ones(len(axes))  # two positions with the bias removed: fit_harmonic stays unweighted
    turn_std, mean_sigma = np.zeros(positions_per_turn), np.zeros(positions_per_turn)
    centre = np.eye(n_turns) - 1.0 / n_turns  # deviations from the mean over turns
    for k in range(positions_per_turn):
        k2 = (k + 1) % positions_per_turn
        w = np.zeros((n_turns, n, len(axes)))  # weights of each turn's azimuth on the position means
        for t in range(n_turns):
            rows = t * positions_per_turn + np.array([k, k2])
            w[t, rows] += _gradient(obs, rows, geom, latitude, azimuth[k], weight, axes)
        if not bias_known:
            w -= w.sum(axis=1, keepdims=True) / n  # the session mean removed from every position
        s = sum(w[:, :, i] @ cov[i] @ w[:, :, i].T for i in range(len(axes)))  # (T, T) generalised
        turn_std[k] = np.sqrt(max(np.trace(centre @ s @ centre), 0.0) / max(n_turns - 1, 1))
        mean_sigma[k] = np.sqrt(max(np.mean(s), 0.0)) if not bias_known else np.nan
    return PairingSpread(turn_std, mean_sigma)
