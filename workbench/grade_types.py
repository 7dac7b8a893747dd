"""Value types of a sensor grade: per-triad 1-sigma spreads, noise terms, range and resolution (SI).

:class:`SensorSpec` (a grade), :class:`TriadSpec`, :class:`NoiseSpec`, :class:`Hysteresis`,
:class:`SpecError`; :data:`FIXTURES`, :data:`TRIADS`, :data:`AXES`. Read from fixtures by
:mod:`workbench.grade_fixtures`; units drawn from them by :mod:`workbench.grades`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from workbench.errors import WorkbenchError
from workbench.model import frozen_finite


FIXTURES = Path(__file__).parents[1] / "fixtures" / "units"
TRIADS = ("gyro", "accel", "mag")
AXES = ("x", "y", "z")


class SpecError(WorkbenchError):
    """A sensor-grade fixture (or a unit truth) is malformed: names the file and field."""


# ---------------------------------------------------------------------------- dataclasses
def _vec3(value, name: str) -> np.ndarray:
    return frozen_finite(np.broadcast_to(np.asarray(value, float), (3,)).copy(), name, SpecError)


@dataclass(frozen=True)
class NoiseSpec:
    """Noise terms of one triad, per axis, SI (u = rad/s, m/s^2 or µT).

    Attributes
    ----------
    white : (3,) white-noise density, u/√Hz (gyro: ARW in rad/√s; accel: VRW in m/s/√s)
    bias_instability : (3,) B, u: flicker floor as in IEEE 952, minimum ADEV = 0.664 B
    rrw : (3,) rate random walk K, u/√s (u/s/√Hz): ADEV = K √(τ/3)
    quantization : (3,) IEEE 952 Q of the integrated output, u·s (rad, m/s, µT·s): ADEV = √3 Q / τ
    resolution : (3,) output LSB, u (rounding of each sample; 0 = none)
    """

    white: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bias_instability: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rrw: np.ndarray = field(default_factory=lambda: np.zeros(3))
    quantization: np.ndarray = field(default_factory=lambda: np.zeros(3))
    resolution: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        for name in ("white", "bias_instability", "rrw", "quantization", "resolution"):
            arr = _vec3(getattr(self, name), name)
            if np.any(arr < 0):
                raise SpecError(f"{name}: negative noise term")
            object.__setattr__(self, name, arr)

    def to_dict(self) -> dict:
        """JSON-ready dict (lists, SI)."""
        return {k: getattr(self, k).tolist() for k in ("white", "bias_instability", "rrw", "quantization",
                                                        "resolution")}


@dataclass(frozen=True)
class Hysteresis:
    """Thermal hysteresis of a triad's bias (a play operator on the unit temperature).

    The bias gains ``gap / 2 * s`` with ``s = (T - p) / width_c`` in [-1, 1], where the play
    point ``p`` follows ``T`` lagging by at most ``width_c``: ``p_k = clip(p_{k-1}, T_k - w,
    T_k + w)``, starting at ``p_0 = T_0`` (s = 0). After warming by more than ``width_c``
    the bias sits on the upper branch (+gap/2) and stays there while the temperature holds;
    after cooling by more than ``width_c`` on the lower branch (-gap/2). ``gap`` is the
    warming-minus-cooling bias difference at the same temperature, (3,) u.
    """

    gap: np.ndarray
    width_c: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "gap", _vec3(self.gap, "bias_hysteresis"))
        if not (np.isfinite(self.width_c) and self.width_c > 0):
            raise SpecError(f"hysteresis_width_c: must be a positive temperature span, got {self.width_c}")

    def to_dict(self) -> dict:
        """JSON-ready dict (SI; width in °C)."""
        return {"gap": self.gap.tolist(), "width_c": float(self.width_c)}


@dataclass(frozen=True)
class TriadSpec:
    """One triad of a grade, SI: 1-sigma spreads of the deterministic errors, noise, range.

    Attributes
    ----------
    range : full-scale input, u (outputs saturate at ±range)
    bias, scale_factor, nonlinearity : (3,) sigma per axis (u; -; 1/u)
    misalignment : (3,) sigma of each off-diagonal element of M in row i (rad)
    g_sensitivity : (3,) sigma of each element of G in row i (rad/s per m/s^2), or None
    bias_temp_poly : (3, K) sigma of the bias coefficient of (T - t_ref)^(k+1), u/°C^(k+1)
    scale_temp_poly : (3, K) sigma of the scale-factor coefficient of (T - t_ref)^(k+1), 1/°C^(k+1)
    noise : NoiseSpec (the grade's values, not spreads)
    hysteresis : Hysteresis or None (fixed values, not spreads)
    sensing_axes : indices of the axes that are real sensing axes (see docs/grades.md)
    """

    range: float
    bias: np.ndarray
    scale_factor: np.ndarray
    misalignment: np.ndarray
    nonlinearity: np.ndarray
    g_sensitivity: np.ndarray | None
    bias_temp_poly: np.ndarray
    scale_temp_poly: np.ndarray
    noise: NoiseSpec
    hysteresis: Hysteresis | None = None
    sensing_axes: tuple[int, ...] = (0, 1, 2)


@dataclass(frozen=True)
class SensorSpec:
    """A sensor grade loaded from a fixture, SI inside (see :func:`load_spec`)."""

    name: str
    description: str
    source: str
    notes: str
    sample_rate_hz: float
    triads: tuple[str, ...]
    t_ref_c: float
    thermal_time_constant_s: float
    temp_sensor_noise_c: float
    specs: Mapping[str, TriadSpec]
    path: Path | None = None
    # the fixture's ``imperfections`` block in SI (virtual-lab defaults, workbench.sim.imperfections):
    # {"warm_up_tau_s": s, "noise_t_ref_c": °C, triad: {field: (3,) SI}}; empty when the grade has none
    imperfections: Mapping = field(default_factory=dict)

    @property
    def gyro(self) -> TriadSpec | None:
        """Gyro triad spec (or None)."""
        return self.specs.get("gyro")

    @property
    def accel(self) -> TriadSpec | None:
        """Accelerometer triad spec (or None)."""
        return self.specs.get("accel")

    @property
    def mag(self) -> TriadSpec | None:
        """Magnetometer triad spec (or None)."""
        return self.specs.get("mag")
