"""Error budget and noise-limited accuracy of north-finding by Earth rate.

* eq. 4.11 / 4.12 (thesis): azimuth error of a maytag pair from a bias shift ``delta_b`` and a
  scale-factor shift ``eps_s`` during the 180° turn, and the inverse: the bias and
  scale-factor stability allowed for a target accuracy at a latitude;
* the noise-limited 1-sigma of one maytag pair from the Allan deviation at the averaging
  time ``T``: the pair difference of two adjacent T-averages has variance ``2 sigma_A(T)^2``
  (definition of the Allan variance; with the turn between them, the Allan variance with that
  dead time, Barnes' B2), so ``(m1 - m2) / 2`` has ``sigma_A / sqrt(2)`` and the
  azimuth ``sigma_A(T) / (sqrt(2) Omega_e cos lat)``; with two axes of different noise
  ``sigma^2 = (sin^2 psi sigma_x^2 + cos^2 psi sigma_y^2) / (2 Omega_N^2)`` (eq. 4.6
  linearised), with one axis (eq. 4.3) ``sigma_x / (sqrt(2) Omega_N |sin psi|)``;
* the noise limit of a sinusoid fit over positions spread round a turn (multi-position,
  carousel): each level axis gives ``n Omega_N^2 / (2 sigma_row^2)`` of information on the
  azimuth (a carousel of ``T_c`` s with ARW ``N``: ``Omega_N^2 T_c / (2 N^2)``);
* the Allan deviation of the IEEE 952 noise model in closed form (white, flicker B with
  ADEV floor ``0.664 B``, rate random walk, quantization);
* paper 001 eq. 48, the gyrocompass accuracy from accelerometer and gyro bias.

All inputs and outputs SI (rad, rad/s, s, dimensionless); lab units only at the edges.

References: thesis (shared/seeds/000_...) eq. 4.11, 4.12, sec. 4.2 (0.023 °/h and 230 ppm at
40.8°); paper 001 (shared/seeds/001_...) eq. 48; IEEE Std 952-1997 annex C.
"""

from __future__ import annotations

import numpy as np

from workbench.allan_model import FLICKER_AVAR, allan_deviation, dead_time_variance  # noqa: F401  (FLICKER_AVAR re-exported)
from workbench.earth import EARTH_RATE
from workbench.errors import AnalysisError

POLE_MARGIN_DEG = 1.0  # deg: no north-finding within this distance of a pole


def check_latitude(latitude: float, where: str = "site") -> None:
    """Raise AnalysisError when ``latitude`` (rad) is within 1° of a pole (no horizontal Earth rate)."""
    if not np.isfinite(latitude) or abs(np.degrees(latitude)) > 90.0 - POLE_MARGIN_DEG:
        raise AnalysisError(f"{where}: latitude {np.degrees(latitude):.3f}° is within {POLE_MARGIN_DEG:g}° of a "
                            "pole: the horizontal Earth rate vanishes and north cannot be found")


def horizontal_rate(latitude: float) -> float:
    """``Omega_e cos(latitude)``, rad/s; raises within 1° of a pole."""
    check_latitude(latitude)
    return float(EARTH_RATE * np.cos(latitude))


def maytag_error(delta_bias: float, scale_shift: float, bias: float, azimuth: float, latitude: float) -> float:
    """Azimuth error (rad) of one maytag pair, thesis eq. 4.11.

    ``eps = [delta_b - eps_s / (1 + eps_s) (-Omega_N cos psi + b2)] / (2 Omega_N sin psi)``
    with ``delta_b`` the bias shift during the turn (rad/s), ``eps_s`` the scale-factor shift
    (dimensionless), ``b2 = bias`` the bias after the turn (rad/s), ``psi`` the azimuth (rad).
    """
    om = horizontal_rate(latitude)
    return float((delta_bias - scale_shift / (1.0 + scale_shift) * (-om * np.cos(azimuth) + bias))
                 / (2.0 * om * np.sin(azimuth)))


def bias_stability_requirement(accuracy: float, latitude: float) -> float:
    """Bias stability over the alignment (rad/s) for an azimuth ``accuracy`` (rad), eq. 4.12.

    ``delta_b = 2 Omega_e cos(lat) eps`` (gyro roughly east or west, scale-factor term apart).
    """
    return 2.0 * horizontal_rate(latitude) * accuracy


def scale_stability_requirement(accuracy: float, latitude: float, bias: float) -> float:
    """Scale-factor stability (dimensionless) for ``accuracy`` (rad) with a bias ``bias`` (rad/s), eq. 4.12.

    ``eps_s = 2 Omega_e cos(lat) eps / |b2|``.
    """
    return 2.0 * horizontal_rate(latitude) * accuracy / abs(bias)


def adev_model(tau: float | np.ndarray, arw: float | np.ndarray = 0.0, bias_instability: float | np.ndarray = 0.0,
               rrw: float | np.ndarray = 0.0, quantization: float | np.ndarray = 0.0,
               spacing: float | None = None) -> np.ndarray:
    """Allan deviation (rad/s) of the IEEE 952 model at ``tau`` (s), with a dead time when ``spacing`` is given.

    ``sigma^2 = N^2/tau + (2 ln2/pi) B^2 + K^2 tau/3 + 3 Q^2/tau^2`` with ``arw`` N (rad/√s),
    ``bias_instability`` B (rad/s, the coefficient: the ADEV floor is 0.664 B), ``rrw`` K
    (rad/s/√s) and ``quantization`` Q (rad). ``spacing`` (s, >= ``tau``): the starts of the two
    averages a maytag pair differences are that far apart (the turn and the settling between
    them); flicker and random walk then decorrelate more than between adjacent averages
    (:func:`workbench.allan_model.dead_time_variance`). Arguments broadcast (e.g. (3,) per axis).
    """
    if spacing is None:
        return allan_deviation(tau, arw, bias_instability, rrw, quantization)
    return np.sqrt(dead_time_variance(tau, spacing, arw, bias_instability, rrw, quantization))


def pair_azimuth_sigma(adev_x: float, latitude: float, adev_y: float | None = None,
                       azimuth: float | None = None) -> float:
    """Noise-limited 1-sigma (rad) of one maytag pair from the Allan deviations at the dwell.

    Two axes (``adev_y`` given): ``sqrt(sin^2 psi sx^2 + cos^2 psi sy^2) / (sqrt(2) Omega_N)``
    (with ``azimuth`` None the two are averaged: ``sqrt((sx^2 + sy^2)/2)``); equal axes give
    ``ADEV(T) / (sqrt(2) Omega_e cos lat)`` whatever the azimuth. One axis (eq. 4.3):
    ``sx / (sqrt(2) Omega_N |sin psi|)`` (``azimuth`` required). ``adev_*`` rad/s; rad.
    """
    om = horizontal_rate(latitude)
    if adev_y is None:
        if azimuth is None:
            raise ValueError("pair_azimuth_sigma: one axis needs the azimuth")
        return float(adev_x / (np.sqrt(2.0) * om * abs(np.sin(azimuth))))
    if azimuth is None:
        mix = np.sqrt(0.5 * (adev_x**2 + adev_y**2))
    else:
        mix = np.sqrt(np.sin(azimuth) ** 2 * adev_x**2 + np.cos(azimuth) ** 2 * adev_y**2)
    return float(mix / (np.sqrt(2.0) * om))


def harmonic_sigma(row_sigma: np.ndarray, n_rows: int, latitude: float) -> float:
    """Noise-limited azimuth 1-sigma (rad) of a sinusoid fit over positions spread evenly round a turn.

    ``row_sigma`` (per level axis) rad/s is the 1-sigma of one row's mean (ADEV at the dwell
    for a static position, ``N / sqrt(T)`` for a carousel lap of ``T`` s with ARW ``N``);
    each axis gives ``n_rows Omega_N^2 / (2 sigma_i^2)`` of information on the azimuth
    (least squares of ``b + A cos + B sin`` over angles evenly spread round the circle).
    """
    om = horizontal_rate(latitude)
    info = np.sum(n_rows * om**2 / (2.0 * np.asarray(row_sigma, float) ** 2))
    return float(1.0 / np.sqrt(info))


def gyrocompass_sigma(accel_bias: float, gyro_bias: float, latitude: float, gravity: float) -> float:
    """Gyrocompass azimuth 1-sigma (rad) of paper 001 eq. 48.

    ``sigma^2 = (sigma_acc / g)^2 + (sigma_gyro / (Omega_e cos L))^2`` with ``accel_bias``
    (m/s^2) and ``gyro_bias`` (rad/s) 1-sigma. The paper prints the gyro term as
    ``sigma_gyro^2 / (|Omega_e| cos^2 L)``; the dimensionally consistent form used here squares
    ``Omega_e`` as well (the classical result: an east gyro bias ``e`` tilts the estimate by
    ``e / (Omega_e cos L)``). Noise is neglected, as in the paper.
    """
    om = horizontal_rate(latitude)
    return float(np.hypot(accel_bias / gravity, gyro_bias / om))
