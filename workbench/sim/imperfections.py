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
- ``scale_drift`` (per triad, 1-sigma, 1/s): scale-factor drift within a run, a linear drift
  ``r t`` of the diagonal scale factor with a fresh rate ``r`` per power-on (t since the first
  sample): ``y = (I + dM + r t) y_model``;
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
the noise of the others (quantisation and saturation are the grade's own noise terms and ranges).

Defaults from the grade: a grade fixture's ``imperfections`` block (lab units, parsed by
:mod:`workbench.grade_fixtures` into ``SensorSpec.imperfections``, SI) gives the values;
:meth:`Imperfections.from_spec` builds them, all of them or the named groups only
(:data:`GROUPS`), with the turntable's own errors added (they belong to the rig, not the unit).

Public: :class:`Imperfections`, :data:`GROUPS`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workbench.errors import WorkbenchError

TRIADS = ("gyro", "accel", "mag")
PER_TRIAD = ("warm_up_bias", "turn_on_bias", "turn_on_scale", "scale_drift", "noise_temp_coeff")
# the names an option switches on: group -> the per-triad fields of a grade block it takes
GROUPS = {"warm_up": ("warm_up_bias",), "turn_on": ("turn_on_bias", "turn_on_scale"),
          "scale_drift": ("scale_drift",), "noise_temp": ("noise_temp_coeff",)}


@dataclass(frozen=True)
class Imperfections:
    """See the module docstring; SI, per triad name."""

    warm_up_bias: dict = field(default_factory=dict)
    warm_up_tau_s: float = 600.0
    turn_on_bias: dict = field(default_factory=dict)
    turn_on_scale: dict = field(default_factory=dict)
    scale_drift: dict = field(default_factory=dict)
    noise_temp_coeff: dict = field(default_factory=dict)
    noise_t_ref_c: float = 25.0
    table_indexing_error: float = 0.0
    table_wobble: float = 0.0
    table_axis_tilt: float = 0.0

    def __post_init__(self) -> None:
        for name in PER_TRIAD:
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

    @property
    def unit(self) -> bool:
        """Whether any imperfection of the unit (not of the table) is on."""
        return any(np.any(self.vector(name, TRIADS)) for name in PER_TRIAD)

    def draw(self, triads: tuple[str, ...], seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """This power-on's bias offset (SI), scale-factor offset (1) and scale-factor drift rate (1/s),
        3 per triad, from ``seed``'s own stream (the first two as before the drift existed)."""
        rng = np.random.default_rng(np.random.SeedSequence([int(seed), 19]))
        z = rng.standard_normal((3, 3 * len(triads)))
        return (z[0] * self.vector("turn_on_bias", triads), z[1] * self.vector("turn_on_scale", triads),
                z[2] * self.vector("scale_drift", triads))

    @classmethod
    def from_spec(cls, spec, groups="all", table_indexing_error: float = 0.0, table_wobble: float = 0.0,
                  table_axis_tilt: float = 0.0) -> "Imperfections":
        """The grade's imperfection block (``spec.imperfections``, SI) as defaults.

        ``groups``: ``"all"``, ``"off"`` (none of the unit's) or a list of :data:`GROUPS` names
        (``warm_up``, ``turn_on``, ``scale_drift``, ``noise_temp``); the table errors (rad) are the
        rig's and given apart. A named group the grade's block does not set is refused, so a
        switched-on imperfection is never silently zero.
        """
        block = dict(getattr(spec, "imperfections", None) or {})
        if groups == "off":
            names: tuple[str, ...] = ()
        elif groups == "all":
            names = tuple(GROUPS)
        else:
            names = tuple(groups)
            unknown = [g for g in names if g not in GROUPS]
            if unknown:
                raise WorkbenchError(f"imperfections: unknown {unknown[0]!r} (known: all, off, {', '.join(GROUPS)})")
        fields = {f for g in names for f in GROUPS[g]}
        values = {f: {t: block[t][f] for t in TRIADS if f in block.get(t, {})} for f in PER_TRIAD if f in fields}
        if groups not in ("all", "off"):
            for g in names:
                if not any(values.get(f) for f in GROUPS[g]):
                    raise WorkbenchError(f"imperfections: grade {getattr(spec, 'name', '?')} has no {g!r} "
                                         "in its imperfections block")
        return cls(**values, warm_up_tau_s=float(block.get("warm_up_tau_s", 600.0)),
                   noise_t_ref_c=float(block.get("noise_t_ref_c", getattr(spec, "t_ref_c", 25.0))),
                   table_indexing_error=table_indexing_error, table_wobble=table_wobble,
                   table_axis_tilt=table_axis_tilt)
