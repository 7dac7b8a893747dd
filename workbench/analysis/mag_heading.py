"""Tilt-compensated heading from a calibrated magnetometer and an accelerometer, and its error.

The heading of the body x axis, clockwise from magnetic north about the down direction,
is computed from vectors (no Euler angles, valid at any tilt except x vertical)::

    d   = -f / |f|                 down, IMU body frame (from specific force f)
    h_h = h - (h . d) d            horizontal field;  x_h = e_x - (e_x . d) d
    psi = atan2((h_h x x_h) . d, h_h . x_h)

This is paper 004's sec. 4.1.1 (remove bank and elevation, then take the heading in the
level plane) written without the rotation sequence. The error against the table's known
azimuth (true heading of the body x axis from the attitude, paper 004 Fig. 15) is
``psi + declination - psi_true``.

Public: :func:`heading`, :func:`true_heading`, :func:`evaluate_heading`, :class:`HeadingEvaluation`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from workbench.angles import wrap_pi as _wrap

_PITCH_LIMIT = np.radians(80.0)  # beyond this the heading of the x axis is ill-defined


def heading(field_body: np.ndarray, down_body: np.ndarray) -> np.ndarray:
    """Magnetic heading (N,) rad of the body x axis from calibrated field (N, 3) µT and unit down (N, 3)."""
    d = down_body / np.linalg.norm(down_body, axis=1, keepdims=True)
    hh = field_body - np.sum(field_body * d, axis=1, keepdims=True) * d
    xh = np.array([1.0, 0.0, 0.0]) - d[:, :1] * d
    return np.arctan2(np.sum(np.cross(hh, xh) * d, axis=1), np.sum(hh * xh, axis=1))


def true_heading(attitude: Rotation) -> np.ndarray:
    """Heading (N,) rad of the body x axis in the reference frame from body-to-reference rotations."""
    x = attitude.apply(np.array([1.0, 0.0, 0.0]))
    return np.arctan2(x[:, 1], x[:, 0])


@dataclass(frozen=True)
class HeadingEvaluation:
    """Heading error of a calibration over a set of points (rad unless named).

    ``reference`` (N,) true heading of body x from the table; ``error`` (N,) = heading +
    declination - reference, wrapped; ``rms`` RMS of ``error``; ``mean`` and ``std`` its
    constant and varying parts; ``declination`` used (rad) and whether it was
    ``declination_estimated`` as the mean offset (then ``rms == std``: a constant error such as
    a yaw misalignment of the magnetometer cannot be seen). ``pitch`` (N,) rad of each point;
    ``tilt_source`` where the down direction came from (``accelerometer``, ``calibrated accelerometer``
    or ``table``).
    """

    reference: np.ndarray
    error: np.ndarray
    pitch: np.ndarray
    rms: float
    mean: float
    std: float
    declination: float
    declination_estimated: bool
    tilt_source: str = "accelerometer"

    def to_dict(self) -> dict:
        """JSON-ready summary (degrees, labelled)."""
        return {"heading_rms_deg": float(np.degrees(self.rms)), "heading_mean_deg": float(np.degrees(self.mean)),
                "heading_std_deg": float(np.degrees(self.std)), "declination_deg": float(np.degrees(self.declination)),
                "declination_estimated": self.declination_estimated, "n_points": int(self.error.size),
                "tilt_source": self.tilt_source}


def evaluate_heading(field_body: np.ndarray, down_body: np.ndarray, attitude: Rotation,
                     declination: float | None = None, tilt_source: str = "accelerometer") -> HeadingEvaluation:
    """Heading error of calibrated field (N, 3) µT against the table attitude (N rotations body->reference).

    ``declination`` rad (field azimuth from the reference x axis); None estimates it as the
    circular mean of the offsets. Points pitched more than 80° are left out.
    """
    ref = true_heading(attitude)
    x = attitude.apply(np.array([1.0, 0.0, 0.0]))
    pitch = -np.arcsin(np.clip(x[:, 2], -1, 1))
    ok = np.abs(pitch) < _PITCH_LIMIT
    psi = heading(field_body[ok], down_body[ok])
    raw = _wrap(psi - ref[ok])
    estimated = declination is None
    decl = -float(np.angle(np.mean(np.exp(1j * raw)))) if estimated else float(declination)
    err = _wrap(raw + decl)
    return HeadingEvaluation(ref[ok], err, pitch[ok], float(np.sqrt(np.mean(err**2))), float(np.mean(err)),
                             float(np.std(err)), decl, estimated, tilt_source)
