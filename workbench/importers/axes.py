"""Axis check on import: the gyro's rotation must agree with the rotation the accelerometer and
magnetometer see.

A direction fixed in space (gravity, the Earth's field) seen in the body frame turns against
the body's rotation: ``du/dt = -w x u = [u]x w`` for a unit vector ``u`` (body frame) and the
body rate ``w`` (rad/s). If the gyro's axes are mapped onto the other sensor's axes by a
signed permutation ``P`` (``w_true = P w_gyro``), then over a window ``du = sum [u]x P w dt``:
linear in the nine entries of ``P``. :func:`check_axes` fits ``P`` by least squares over short
windows of moving stretches (the directions averaged over a few samples, so the hand's
acceleration averages out), and compares every signed permutation (48: the 24 rotations and
their mirror images) by the residual of the windows. The identity fits when the profile's
axis mapping is right; otherwise the best permutation names the sign and the axes to change.

Public: :func:`check_axes` -> :class:`AxisCheck`, :func:`signed_permutations`.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import permutations, product

import numpy as np

WINDOW_S = 0.5  # window over which a direction change is compared with the integrated gyro
MIN_TURN = np.radians(8.0)  # a window must turn the direction by this much to count
MIN_WINDOWS = 5  # fewer turning windows: no verdict
CLEAR = 0.5  # another mapping must fit this much better (rms ratio) than the profile's to be a disagreement


def signed_permutations() -> list[np.ndarray]:
    """The 48 signed 3x3 permutation matrices (identity first)."""
    out = []
    for perm in permutations(range(3)):
        for signs in product((1.0, -1.0), repeat=3):
            m = np.zeros((3, 3))
            m[np.arange(3), perm] = signs
            out.append(m)
    return out


def describe(p: np.ndarray, prefix: str = "g") -> str:
    """``p`` as axis assignments: ``gx <- -gx, gy <- gz, gz <- gy`` (what the profile should map)."""
    parts = []
    for i in range(3):
        j = int(np.argmax(np.abs(p[i])))
        sign = "-" if p[i, j] < 0 else ""
        parts.append(f"{prefix}{'xyz'[i]} <- {sign}{prefix}{'xyz'[j]}")
    return ", ".join(parts)


@dataclass(frozen=True)
class AxisCheck:
    """The result for one reference sensor (``accel`` or ``mag``) against the gyro.

    ``best`` the signed permutation with the smallest residual (``w_true = best @ w_gyro``),
    ``rms_identity_deg`` / ``rms_best_deg`` the rms direction error of the windows (degrees)
    with the identity and with ``best``; ``windows`` how many windows moved enough;
    ``agrees`` whether the profile's mapping (the identity) fits: no other fits twice as well
(None: fewer than :data:`MIN_WINDOWS` windows turned enough to tell).
    """

    reference: str
    best: np.ndarray
    rms_identity_deg: float
    rms_best_deg: float
    windows: int

    @property
    def agrees(self) -> bool | None:
        """True / False, or None without enough motion to tell."""
        if self.windows < MIN_WINDOWS:
            return None
        return bool(np.allclose(self.best, np.eye(3)) or self.rms_best_deg > CLEAR * self.rms_identity_deg)

    def message(self) -> str:
        """One line for the import summary."""
        if self.agrees is None:
            return (f"axis check gyro vs {self.reference}: not enough motion ({self.windows} windows of "
                    f"{WINDOW_S:g} s turned the direction {np.degrees(MIN_TURN):.0f}°, {MIN_WINDOWS} needed)")
        if self.agrees:
            return (f"axis check gyro vs {self.reference}: axes agree ({self.windows} windows, "
                    f"rms {self.rms_identity_deg:.1f}°)")
        return (f"axis check gyro vs {self.reference}: DISAGREE: the gyro's rotation fits the {self.reference} "
                f"with {describe(self.best)} (rms {self.rms_best_deg:.1f}° vs {self.rms_identity_deg:.1f}° as "
                f"mapped, {self.windows} windows)")


def _windows(t: np.ndarray, gyro: np.ndarray, ref: np.ndarray, good: np.ndarray,
             window_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Windows that turned: start and end directions (W, 3), the rates (W, S, 3) and intervals (W, S)."""
    dt = np.diff(t, append=t[-1])
    step = max(2, int(round(window_s / max(float(np.median(np.diff(t))), 1e-9))))
    avg = max(1, step // 4)
    u = ref / np.linalg.norm(ref, axis=1, keepdims=True)
    starts = np.arange(0, len(t) - step - avg, step)
    if not len(starts):
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, step, 3)), np.zeros((0, step))
    ok = np.array([good[a:a + step + avg].all() for a in starts])
    starts = starts[ok]
    mean = lambda a: u[a[:, None] + np.arange(avg)].mean(1)  # noqa: E731 - directions over avg samples
    u0, u1 = mean(starts), mean(starts + step)
    u0 /= np.linalg.norm(u0, axis=1, keepdims=True)
    u1 /= np.linalg.norm(u1, axis=1, keepdims=True)
    turned = np.arccos(np.clip(np.sum(u0 * u1, axis=1), -1, 1)) >= MIN_TURN
    rows = (starts[turned] + avg // 2)[:, None] + np.arange(step)
    return u0[turned], u1[turned], gyro[rows], dt[rows]


def _rms_error(p: np.ndarray, u0: np.ndarray, u1: np.ndarray, w: np.ndarray, dt: np.ndarray) -> float:
    """Rms angle (rad) between each window's end direction and its start direction carried by ``p @ w``."""
    v = u0.copy()
    wp = w @ p.T
    for k in range(w.shape[1]):
        v = v + np.cross(v, wp[:, k]) * dt[:, k, None]  # du/dt = u x w
        v /= np.linalg.norm(v, axis=1, keepdims=True)
    return float(np.sqrt(np.mean(np.arccos(np.clip(np.sum(v * u1, axis=1), -1, 1)) ** 2)))


def check_axes(t: np.ndarray, gyro: np.ndarray, ref: np.ndarray, reference: str,
               good: np.ndarray | None = None, window_s: float = WINDOW_S) -> AxisCheck:
    """Compare the gyro (N, 3, rad/s, body) with the direction changes of ``ref`` (N, 3: specific force or
    field, any unit) at instants ``t`` (N,) s; ``good`` (N,) leaves flagged samples out."""
    good = np.ones(len(t), bool) if good is None else good
    wins = _windows(t, gyro, ref, good, window_s)
    if not len(wins[0]):
        return AxisCheck(reference, np.eye(3), float("nan"), float("nan"), 0)
    scores = [(_rms_error(p, *wins), i, p) for i, p in enumerate(signed_permutations())]
    best = min(scores, key=lambda s: (s[0], s[1]))
    return AxisCheck(reference, best[2], float(np.degrees(scores[0][0])), float(np.degrees(best[0])), len(wins[0]))
