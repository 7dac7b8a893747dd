"""Angle wrapping, written once: every module that wraps an angle uses these.

:func:`wrap_pi` to [-pi, pi), :func:`wrap_2pi` to [0, 2 pi), :func:`angle_diff` (a - b wrapped
to [-pi, pi]), :func:`circular_mean` (the mean direction). All in rad; scalars give floats, arrays give arrays.
"""

from __future__ import annotations

import numpy as np


def wrap_pi(a):
    """``a`` (rad, scalar or array) wrapped to [-pi, pi)."""
    out = (np.asarray(a, float) + np.pi) % (2 * np.pi) - np.pi
    return float(out) if out.ndim == 0 else out


def wrap_2pi(a):
    """``a`` (rad, scalar or array) wrapped to [0, 2 pi)."""
    out = np.mod(np.asarray(a, float), 2 * np.pi)
    return float(out) if out.ndim == 0 else out


def angle_diff(a, b) -> np.ndarray:
    """``a - b`` (rad) wrapped to [-pi, pi] through the unit circle (exact at the branch: +-pi)."""
    return np.angle(np.exp(1j * (np.asarray(a, float) - np.asarray(b, float))))


def circular_mean(angles) -> float:
    """Mean direction of ``angles`` (rad), in (-pi, pi]: the argument of the mean unit vector."""
    return float(np.angle(np.mean(np.exp(1j * np.asarray(angles, float)))))
