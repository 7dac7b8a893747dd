"""Imperfections of real units that the grade's error model leaves out (issue 19 item 4, in part).

The virtual IMU follows ``TriadModel`` exactly: a unit's bias and scale factor are the same at
every power-on and from the first sample on. Real units are not so kind (thesis sec. 1.3: 17 mg
residuals where the model gives 0.2 mg). Each imperfection here has its own field, all off by
default, so a simulation without them is sample-for-sample what it was:

- ``warm_up_bias`` (per triad, (3,) SI) and ``warm_up_tau_s``: a bias transient after power-on,
  ``b_w exp(-t / tau)`` with t the time since the first sample of the recording;
- ``turn_on_bias`` (per triad, (3,) SI, 1-sigma): run-to-run bias repeatability, a fresh offset
  drawn at every power-on (every recording's seed), constant within the run;
- ``turn_on_scale`` (per triad, 1-sigma, dimensionless): run-to-run scale-factor repeatability,
  a fresh diagonal ``dM`` per power-on: ``y = (I + dM) y_model``;
- ``noise_temp_coeff`` (per triad, 1/°C): the noise grows by ``1 + c (T - noise_t_ref_c)`` with the
  unit temperature (every noise term's output is scaled: the white noise dominates at the sample rate).

Of the turntable (used by :class:`~workbench.sim.rig.SimRig`; radians, SI like the rest):

- ``table_indexing_error``: a systematic, repeatable angle error beyond the random 0.01°
  positioning, ``e(theta) = a sin(theta)`` (encoder eccentricity: the same error at the same
  position every time); the true table angle is ``theta + e(theta)``, the encoder reads ``theta``;
- ``table_wobble``: the axis rocking once per revolution, a tilt ``w sin(theta)`` of the platform
  about the base's horizontal x axis (a tilt that turns rigidly with the table would be a mounting
  tilt, which every calibration absorbs; the wobble is the part that changes with the angle);
- ``table_axis_tilt``: the axis misaligned from the local vertical by a fixed tilt about the base's
  x axis, the same at every table angle (a level table has none).

The draws come from their own child of the recording's seed, so turning one on does not change
the noise of the others. Not modelled yet: scale-factor drift within a run, quantisation and saturation,
grade defaults (each imperfection is an explicit option).

Public: :class:`Imperfections`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workbench.errors import WorkbenchError

TRIADS = ("gyro", "accel", "mag")


@dataclass(frozen=True)
class Imperfections:
    """See the module docstring; SI, per triad name."""

    warm_up_bias: dict = field(default_factory=dict)
    warm_up_tau_s: float = 600.0
    turn_on_bias: dict = field(default_factory=dict)
    turn_on_scale: dict = field(default_factory=dict)
    noise_temp_coeff: dict = field(default_factory=dict)
    noise_t_ref_c: float = 25.0
    table_indexing_error: float = 0.0
    table_wobble: float = 0.0
    table_axis_tilt: float = 0.0

    def __post_init__(self) -> None:
        for name in ("warm_up_bias", "turn_on_bias", "turn_on_scale", "noise_temp_coeff"):
            unknown = set(getattr(self, name)) - set(TRIADS)
            if unknown:
                raise WorkbenchError(f"imperfections.{name}: unknown triad(s) {sorted(unknown)}")
        if not self.warm_up_tau_s > 0:
            raise WorkbenchError(f"imperfections.warm_up_tau_s: {self.warm_up_tau_s} s must be positive")
        for name in ("table_indexing_error", "table_wobble", "table_axis_tilt"):
            if not abs(getattr(self, name)) < np.radians(10.0):
                raise WorkbenchError(f"imperfections.{name}: {getattr(self, name)} rad is not a small angle")

    @property
    def table(self) -> bool:
        """Whether any turntable imperfection is on."""
        return bool(self.table_indexing_error or self.table_wobble or self.table_axis_tilt)

    def vector(self, name: str, triads: tuple[str, ...]) -> np.ndarray:
        """Field ``name`` stacked over ``triads`` (3 per triad), zeros where a triad has none."""
        return np.concatenate([np.broadcast_to(np.asarray(getattr(self, name).get(t, 0.0), float), (3,))
                               for t in triads])

    def draw(self, triads: tuple[str, ...], seed: int) -> tuple[np.ndarray, np.ndarray]:
        """This power-on's bias offset and scale-factor offset (3 per triad), from ``seed``'s own stream."""
        rng = np.random.default_rng(np.random.SeedSequence([int(seed), 19]))
        z = rng.standard_normal((2, 3 * len(triads)))
        return z[0] * self.vector("turn_on_bias", triads), z[1] * self.vector("turn_on_scale", triads)
