"""North-finding from Earth-rate measurements on an indexing or rotating table.

Estimators of the azimuth of the body x axis at the table's zero (clockwise from true north)
from gyro outputs against the table angle:

* maytagging, two positions 180° apart: eq. 4.6 (two horizontal axes, atan2, no latitude
  needed) and eq. 4.3 (one axis, arccos, with its ±180° ambiguity);
* multi-position and carousel: linear least squares of
  ``rate_i = b_i [+ d_i t] + g_i Omega_N cos(psi + alpha_i + a)`` over every horizontal axis
  ``i`` (``a`` table angle, ``alpha_i`` the axis direction relative to body x, ``g_i`` its
  horizontal projection), i.e. ``b + A cos(a) + B sin(a)`` per axis with ``A, B`` shared
  through ``(Omega_N cos psi, Omega_N sin psi)``;
* the redundant-gyro configuration of sec. 4.4.3: two consecutive 45° positions of a two-axis
  gyro taken as one skewed four-axis configuration (axes at psi, psi+45°, psi+90°, psi+135°),
  biases removed with a known (turn-averaged or calibrated) bias.

Frames: body x fwd, y right, z down; table-top frame x along the table's zero, z down; table
angle ``a`` positive clockwise from above; Earth rate in NED ``Omega_e (cos lat, 0, -sin lat)``.
The body rate at table angle ``a`` is ``mount.T @ (Rz(a).T Rz(az0).T Omega_ned + (0, 0, r))``
(``r`` the table rate), so axis ``i`` with table-frame direction ``mount[:, i]`` sees
``g_i Omega_N cos(az0 + alpha_i + a) - d_i (Omega_e sin lat - r)`` with ``d_i = mount[2, i]``.

Public: :class:`Observations`, :class:`AxisGeometry`, :class:`HarmonicFit`,
:class:`MaytagResult`, :class:`RedundantResult`, :func:`maytag_azimuth`,
:func:`maytag_azimuth_one_axis`, :func:`fit_harmonic`, :func:`maytag`, :func:`redundant`,
:func:`group_fits`, :func:`static_observations`, :func:`rotating_observations`,
:func:`find_north`, :class:`NorthFinding`, :func:`to_result`,
:func:`earth_rate_free_series`, :func:`sequence_table`, :func:`pairing_table`,
:func:`circular_mean`, :func:`angle_diff`, :func:`repeatability`.

References: thesis (shared/seeds/000_...) sec. 4.2 eq. 4.1-4.6, sec. 4.4.1-4.4.3,
tables 4.2-4.4.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from workbench.analysis.northfinding_data import (STATIC_RATE_TOL, AxisGeometry, Observations, _Samples,  # noqa: F401
                                                  angle_diff, circular_mean, rotating_observations,
                                                  static_observations)
from workbench.analysis.northfinding_fit import (HarmonicFit, MaytagResult, RedundantResult, fit_harmonic,  # noqa: F401
                                                 group_fits, maytag, maytag_azimuth, maytag_azimuth_one_axis,
                                                 redundant, repeatability)
from workbench.analysis.northfinding_report import pairing_table, sequence_table, to_result  # noqa: F401
from workbench.analysis.northfinding_theory import check_latitude
from workbench.angles import wrap_2pi
from workbench.errors import AnalysisError
from workbench.session import Session

if TYPE_CHECKING:
    from workbench.grades import SensorSpec


# -- a whole session ----------------------------------------------------------------------

METHODS = ("maytagging", "multiposition", "carousel", "redundant")


@dataclass(frozen=True)
class NoiseTerms:
    """Gyro noise terms per body axis, SI, for the theoretical figures, and where they come from.

    ``arw`` (3,) rad/√s, ``bias_instability`` (3,) rad/s (IEEE 952 B), ``rrw`` (3,) rad/s/√s,
    ``quantization`` (3,) rad; ``source`` e.g. ``"grade cvg_two_axis"``.
    """

    arw: np.ndarray
    bias_instability: np.ndarray
    rrw: np.ndarray
    quantization: np.ndarray
    source: str

    @classmethod
    def from_spec(cls, spec) -> NoiseTerms:
        """From a grade (``workbench.grades.SensorSpec``) gyro noise."""
        nz = spec.specs["gyro"].noise
        return cls(nz.white, nz.bias_instability, nz.rrw, nz.quantization, f"grade {spec.name}")


@dataclass(frozen=True)
class NorthFinding:
    """North-finding result of one session (all SI; see :func:`find_north`).

    ``azimuth`` rad of body x at the table's zero, clockwise from true north, and its 1-sigma
    ``azimuth_sigma`` (std of the units / sqrt(count) with 3 or more units, else formal);
    ``units`` (pairs, turns, laps, or pairing estimates) with ``unit_azimuth`` (U,) rad,
    ``unit_time`` (U,) s and ``unit_std`` rad; ``gyro_bias`` (3,) rad/s with ``gyro_bias_sigma``
    (NaN: not observed); ``earth_rate_amplitude`` rad/s (NaN: not observed with one axis) against
    ``expected_amplitude = Omega_e cos lat``; ``averaging_time`` s of one row (mean);
    ``theory`` rad: ``arw_unit_sigma``, ``allan_unit_sigma``, with ``adev_at_dwell`` (3,) rad/s
    and ``source``; ``true_azimuth`` rad when the session knows the table's zero azimuth.
    """

    method: str
    units: str
    azimuth: float
    azimuth_sigma: float
    unit_azimuth: np.ndarray
    unit_time: np.ndarray
    unit_std: float
    gyro_bias: np.ndarray
    gyro_bias_sigma: np.ndarray
    earth_rate_amplitude: float
    earth_rate_amplitude_sigma: float
    expected_amplitude: float
    latitude: float
    averaging_time: float
    theory: dict
    true_azimuth: float | None
    obs: Observations
    geometry: AxisGeometry
    fit: HarmonicFit
    detail: MaytagResult | RedundantResult | None
    ambiguous: bool
    warnings: tuple[str, ...]

    @property
    def azimuth_error(self) -> float | None:
        """Estimated minus true azimuth, rad (None when the table's zero azimuth is unknown)."""
        return None if self.true_azimuth is None else float(angle_diff(self.azimuth, self.true_azimuth))

    def to_dict(self) -> dict:
        """JSON-ready result (``result.json``'s ``result``; keys name their lab unit, e.g. ``azimuth_deg``)."""
        return to_result(self)[0]

    def summary(self) -> list[str]:
        """Lines for people: azimuth (°) and its sigma (mrad), per-unit scatter against theory, warnings aside."""
        return to_result(self)[1]


def _session_mount(session: Session, obs: Observations, max_tilt: float, axes: Sequence[int]) -> AxisGeometry:
    """The one mount of the rows' steps, checked level for the sensing ``axes`` (AnalysisError naming the step)."""
    mounts = [session.step(int(i)).mount for i in np.unique(obs.step)]
    for i, m in zip(np.unique(obs.step), mounts):
        if not np.allclose(m, mounts[0], atol=1e-9):
            raise AnalysisError(f"{session.name}: step {i}: mount differs from step {obs.step[0]}'s; "
                                "north-finding needs one mount")
    return AxisGeometry.from_mount(mounts[0], max_tilt, f"{session.name}: step {int(obs.step[0])} mount", axes)


def _accel_tilt_warning(session: Session, steps: np.ndarray, geom: AxisGeometry, max_tilt: float) -> list[str]:
    """Warn when the accelerometers show a level gyro axis tilted beyond ``max_tilt`` (rad)."""
    data = _Samples(session)
    cuts = [data.cut(st, 0.0, static=st.kind == "static") for st in (session.step(int(i)) for i in np.unique(steps))]
    f = np.mean([c["accel"].mean(axis=0) for c in cuts], axis=0)
    tilt = np.arcsin(np.clip(np.abs(f) / np.linalg.norm(f), 0.0, 1.0))
    bad = [i for i in np.flatnonzero(geom.horizontal) if tilt[i] > max_tilt]
    return [f"{session.name}: accelerometers show body {'xyz'[i]} tilted {np.degrees(tilt[i]):.2f}° from level "
            f"(limit {np.degrees(max_tilt):.2f}°): the table or the fixture is not level" for i in bad]


def earth_rate_free_series(session: Session, obs: Observations, fit: HarmonicFit, geom: AxisGeometry,
                           settle_s: float) -> np.ndarray:
    """Gyro samples (N, 3) rad/s of the rows' steps with the fitted Earth rate and table rate removed.

    Static and rotating steps alike (each sample at its own table angle), after ``settle_s``,
    concatenated in time order: the bias + noise series the Allan deviation is taken on
    (the index moves between steps are skipped, so the record is treated as contiguous).
    """
    lat = session.site.latitude
    data = _Samples(session)
    parts = []
    for idx in np.unique(obs.step):
        st = session.step(int(idx))
        c = data.cut(st, settle_s, static=st.kind == "static")
        model = fit.model(c["angle"], geom, lat) - fit.bias + geom.down * c["rate"][:, None]
        parts.append(c["gyro"] - model)
    return np.concatenate(parts)


def _data_adev(series: np.ndarray, rate_hz: float, tau: float, where: str) -> np.ndarray:
    """Overlapping ADEV (3,) rad/s at ``tau`` s of a series (workbench.analysis.allan)."""
    from workbench.analysis.allan import deviation

    if len(series) < 3 * tau * rate_hz:
        raise AnalysisError(f"{where}: {len(series) / rate_hz:.0f} s of data cannot give the Allan deviation "
                            f"at {tau:.0f} s")
    curve = deviation(series, rate_hz, "oadev", taus=np.array([tau]), source=where)
    return curve.dev[0]


def _theory(method: str, nf_parts: dict, noise: NoiseTerms | None, series_fn, session: Session,
            geom: AxisGeometry) -> dict:
    """Theoretical per-unit 1-sigma (rad) from ARW alone and from the ADEV at the unit's averaging time.

    A maytag pair's ``nf_parts["spacing"]`` (s between the starts of its two averages) makes the
    grade's ADEV the one with that dead time; the data's own ADEV (no noise model) has none. With a
    grade, the redundant method also gets ``pairing_spread`` (:mod:`northfinding_spread`: the std
    over turns and the sigma of the session mean per pairing, bias wander included).
    """
    from workbench.analysis import northfinding_theory as th

    lat = session.site.latitude
    hz = np.flatnonzero(geom.horizontal)
    tau = nf_parts["tau"]
    if noise is not None:
        adev = th.adev_model(tau, noise.arw, noise.bias_instability, noise.rrw, noise.quantization,
                             spacing=nf_parts.get("spacing"))
        white = noise.arw / np.sqrt(tau)
        source = noise.source
    else:
        adev = _data_adev(series_fn(), session.sample_rate_hz, tau, session.name)
        white = np.full(3, np.nan)  # no ARW without a noise model: not observed
        source = f"data: overlapping ADEV at {tau:.1f} s of the Earth-rate-free series"
    out = {"source": source, "tau": float(tau), "spacing": float(nf_parts.get("spacing", tau)), "adev_at_dwell": adev}
    if method == "redundant" and noise is not None:
        from workbench.analysis.northfinding_spread import redundant_spread

        obs, per_turn, azimuth, known = nf_parts["spread_inputs"]
        out["pairing_spread"] = redundant_spread(obs, geom, lat, per_turn, azimuth, known, {
            "arw": noise.arw, "bias_instability": noise.bias_instability, "rrw": noise.rrw,
            "quantization": noise.quantization})
    for key, sig in (("arw_unit_sigma", white), ("allan_unit_sigma", adev)):
        if not np.all(np.isfinite(sig[hz])):
            out[key] = float("nan")
        elif method in ("maytagging", "redundant"):
            psi = nf_parts.get("home_azimuth")
            out[key] = (th.pair_azimuth_sigma(sig[hz[0]], lat, sig[hz[1]], psi) if len(hz) > 1
                        else th.pair_azimuth_sigma(sig[hz[0]], lat, None, psi))
        else:
            out[key] = th.harmonic_sigma(sig[hz] / geom.gain[hz], nf_parts["rows_per_unit"], lat)
    return out


@dataclass(frozen=True)
class _MethodFit:
    """What one method gives :func:`find_north`: the fit of all rows, the per-unit azimuths (rad)."""

    fit: HarmonicFit
    units: str  # what one unit is: pair, turn, lap, pairing estimate
    unit_azimuth: np.ndarray
    unit_time: np.ndarray
    azimuth: float
    detail: MaytagResult | RedundantResult | None = None
    ambiguous: bool = False
    azimuth_sigma: float | None = None  # None: the units' spread / sqrt(n) with 3 or more, else the fit's
    parts: dict = field(default_factory=dict)  # inputs of the theoretical figures (_theory)
    warnings: tuple[str, ...] = ()


def _maytagging(session, obs, geom, lat, drift, where, index_tol, pairs, **_) -> _MethodFit:
    """Pairs of static steps 180° apart, eq. 4.6 (eq. 4.3 with one level axis), disjoint or sliding."""
    d = maytag(obs, geom, lat, index_tol, drift, where, pairs)
    return _MethodFit(d.fit, "pair", d.pair_azimuth, d.pair_time, d.azimuth, d, d.ambiguous,
                      azimuth_sigma=d.azimuth_sigma,
                      parts={"home_azimuth": float(d.azimuth + obs.angle[0]), "spacing": _pair_spacing(obs)},
                      warnings=tuple(d.warnings))


def _pair_spacing(obs) -> float:
    """Median time (s) between consecutive static positions (rows in time order, as find_north sorts them): how
    far apart a pair's two averages start."""
    t = obs.t
    return float(max(np.median(np.diff(t)), np.mean(obs.duration))) if len(t) > 1 else float(np.mean(obs.duration))


def _redundant(session, obs, geom, lat, drift, where, positions_per_turn, bias, **_) -> _MethodFit:
    """The eight pairings of 45° steps (sec. 4.4.3); 1-sigma from the spread of the turn means."""
    d = redundant(obs, geom, lat, positions_per_turn or 8, bias, where=where)
    fit = fit_harmonic(obs, geom, lat, drift=drift, where=where)
    n_turns = d.azimuth.shape[0]
    sigma = float(np.std([circular_mean(d.azimuth[t]) for t in range(n_turns)], ddof=1) / np.sqrt(n_turns)) \
        if n_turns >= 3 else fit.azimuth_sigma
    unit_az = d.azimuth.ravel()
    per_turn = positions_per_turn or 8
    return _MethodFit(fit, "pairing estimate", unit_az, np.repeat(d.turn_time, len(d.pairings)),
                      circular_mean(unit_az), d, azimuth_sigma=sigma,
                      parts={"spread_inputs": (obs, per_turn, d.mean, bias is not None)})


def _per_unit(obs, groups, geom, lat, where, fit, units) -> _MethodFit:
    """One harmonic fit per complete group (turn or lap) beside the fit of all rows."""
    labels, counts = np.unique(groups, return_counts=True)
    full = labels[counts >= 0.9 * counts.max()]  # complete turns / laps only (bins need not align with laps)
    keep = np.isin(groups, full)
    unit_az = group_fits(obs.subset(keep), groups[keep], geom, lat, where)
    unit_t = np.array([obs.t[groups == g].mean() for g in full])
    return _MethodFit(fit, units, unit_az, unit_t, fit.azimuth, parts={"rows_per_unit": int(counts.max()),
                                                                       "full": full, "groups": groups})


def _multiposition(session, obs, geom, lat, drift, where, positions_per_turn, **_) -> _MethodFit:
    """Static steps round the turn: one fit of all, one per turn of ``positions_per_turn``."""
    fit = fit_harmonic(obs, geom, lat, drift=drift, where=where)
    per = positions_per_turn or len(np.unique(np.round(wrap_2pi(obs.angle), 4)))
    m = _per_unit(obs, np.arange(len(obs)) // per, geom, lat, where, fit, "turn")
    return replace(m, parts={"rows_per_unit": m.parts["rows_per_unit"]})


def _carousel(session, obs, geom, lat, drift, where, **_) -> _MethodFit:
    """Binned continuous rotation: one fit of all, one per lap (laps counted from each step's start)."""
    fit = fit_harmonic(obs, geom, lat, drift=drift, where=where)
    rate = np.array([session.step(int(i)).table_rate for i in obs.step])
    t0 = np.array([session.step(int(i)).t_start for i in obs.step])
    groups = obs.step * 100000 + np.floor(np.abs(rate) * (obs.t - t0) / (2 * np.pi)).astype(int)
    m = _per_unit(obs, groups, geom, lat, where, fit, "lap")
    # one lap is one row of its whole duration
    tau = float(np.sum(obs.duration[groups == m.parts["full"][0]]))
    return replace(m, parts={"tau": tau, "rows_per_unit": 1})


# method -> (observations: static steps or rotating bins, estimator)
_METHODS = {"maytagging": ("static", _maytagging), "multiposition": ("static", _multiposition),
            "carousel": ("rotating", _carousel), "redundant": ("static", _redundant)}


def find_north(session: Session, method: str, settle_s: float = 2.0, drift: bool | None = None,
               index_tol_deg: float = 0.05, max_tilt_deg: float = 1.0, grade: SensorSpec | None = None,
               bias: np.ndarray | None = None, positions_per_turn: int | None = None,
               bin_deg: float = 5.0, axes: Sequence[int] | None = None, discard_s: float = 0.0,
               pairs: str = "disjoint") -> NorthFinding:
    """Find north from a session with ``method`` in :data:`METHODS`.

    * ``maytagging``: static steps paired in time order, 180° apart within ``index_tol_deg``,
      ``pairs`` ``"disjoint"`` ((0, 1), (2, 3), ...) or ``"sliding"`` ((0, 1), (1, 2), ...: thesis
      sec. 4.4.2, an azimuth every dwell);
    * ``multiposition``: static steps evenly spread round the turn (Earth-rate sweep), one
      fit per turn of ``positions_per_turn`` (default: the distinct angles) and one of all;
    * ``carousel``: the ``carousel`` steps binned by ``bin_deg``, one fit per lap and one of all;
    * ``redundant``: static 45° steps, the eight pairings of sec. 4.4.3 (``bias`` (3,) rad/s
      removes a known bias; default the turn mean).

    ``settle_s`` s dropped at the start of each step; ``drift`` fits a linear bias drift
    (default: off for maytagging, on otherwise); ``max_tilt_deg``: body x must be level and
    other axes level or vertical within it; ``grade``: the grade (a
    :class:`~workbench.grades.SensorSpec`, given by the caller: an analysis reads no fixture)
    whose noise terms give the theoretical figures (default: the session's own ADEV);
    ``axes``: the gyro's sensing axes (default: the grade's ``sensing_axes``, else all three);
    ``discard_s``: steps that start less than this after the session's first sample are left
    out (warm-up: thesis table 4.2, sequences 8-11 "extracted one hour after the starting").
    The azimuth never uses the site's ``table_zero_azimuth_deg``; when known it gives
    ``true_azimuth``.
    """
    from workbench.analysis.northfinding_theory import horizontal_rate

    if method not in METHODS:
        raise AnalysisError(f"{session.name}: unknown north-finding method {method!r} "
                            f"(expected one of {', '.join(METHODS)})")
    lat = session.site.latitude
    check_latitude(lat, f"{session.name}: site.latitude_deg")
    max_tilt = np.radians(max_tilt_deg)
    spec = grade
    drift = (method != "maytagging") if drift is None else bool(drift)
    where = f"{session.name}: {method}"
    obs = rotating_observations(session, settle_s, bin_deg) if _METHODS[method][0] == "rotating" \
        else static_observations(session, settle_s)
    obs = obs.subset(np.argsort(obs.t))
    if discard_s > 0:
        t0 = float(session.samples["t"].iloc[0])
        obs = obs.subset(np.array([session.step(int(i)).t_start - t0 >= discard_s for i in obs.step], bool))
        if len(obs) == 0:
            raise AnalysisError(f"{session.name}: {method}: no step starts after the {discard_s:g} s discarded "
                                "for warm-up")
    if axes is None:
        axes = spec.specs["gyro"].sensing_axes if spec is not None else (0, 1, 2)
    geom = _session_mount(session, obs, max_tilt, axes)
    warnings = _accel_tilt_warning(session, obs.step, geom, max_tilt)
    m = _METHODS[method][1](session, obs, geom, lat, drift, where, index_tol=np.radians(index_tol_deg),
                            positions_per_turn=positions_per_turn, bias=bias, pairs=pairs)
    fit, detail, ambiguous, units = m.fit, m.detail, m.ambiguous, m.units
    unit_az, unit_t, azimuth = m.unit_azimuth, m.unit_time, m.azimuth
    warnings += list(m.warnings)
    parts: dict = {"tau": float(np.mean(obs.duration)), **m.parts}
    n_units = len(unit_az)
    dev = angle_diff(unit_az, azimuth) if n_units else np.zeros(0)
    unit_std = float(np.std(dev, ddof=1)) if n_units > 1 else float("nan")
    az_sigma = m.azimuth_sigma if m.azimuth_sigma is not None else \
        (unit_std / np.sqrt(n_units) if n_units >= 3 else fit.azimuth_sigma)
    amp, amp_sigma = (float("nan"), float("nan")) if ambiguous else (fit.amplitude, fit.amplitude_sigma)
    expected = horizontal_rate(lat)
    if np.isfinite(amp) and abs(amp / expected - 1.0) > max(0.05, 5 * amp_sigma / expected):
        warnings.append(f"{where}: fitted horizontal Earth rate {amp / expected:.4f} x Omega_e cos(lat): "
                        "a scale-factor error or a wrong site latitude")
    noise = NoiseTerms.from_spec(spec) if spec is not None and "gyro" in spec.specs else None
    theory = _theory(method, parts, noise,
                     lambda: earth_rate_free_series(session, obs, fit, geom, settle_s), session, geom)
    az0 = session.site.table_zero_azimuth
    true_az = None if az0 is None else float(angle_diff(az0 + geom.heading, 0.0))
    return NorthFinding(method, units, float(azimuth), float(az_sigma), np.asarray(unit_az), np.asarray(unit_t),
                        unit_std, fit.bias, fit.bias_sigma, amp, amp_sigma, expected, lat, float(np.mean(obs.duration)),
                        theory, true_az, obs, geom, fit, detail, ambiguous, tuple(warnings))
