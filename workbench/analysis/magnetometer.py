"""Magnetometer calibration: hard iron, soft iron, alignment to the IMU, heading accuracy.

Entry points:

- :func:`points_from_session`: the points a fit uses, from a session: one mean per static
  step, block means of at most ``block_deg`` of table rotation in rate steps, each with the
  accelerometer mean and the body-to-reference attitude from the table angle and mount.
- :func:`calibrate`: checks the input, chooses the estimator (:mod:`mag_select`) unless told,
  fits it (:mod:`mag_fit2d`, :mod:`mag_ellipsoid`, :mod:`mag_attitude`), assesses coverage
  and residuals (:mod:`mag_quality`) and the heading error against the table
  (:mod:`mag_heading`), optionally against the IGRF field (:mod:`mag_reference`); returns a
  :class:`MagCalibration`.
- :func:`triad_calibration`: the calibration set's ``mag`` block from a fit: ``bias`` = hard
  iron µT, ``scale_misalignment`` = ``M`` with ``I + M`` the soft-iron distortion
  (``measured = (I + M) true + bias``), ``field_norm_ut``, sigmas (NaN = not observed).

The model and the scale convention are in :mod:`workbench.analysis.mag_fit`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from workbench import units
from workbench.analysis import mag_attitude, mag_ellipsoid, mag_fit2d, mag_quality, mag_reference, mag_select, mag_spikes
from workbench.analysis.mag_fit import FIELD_RANGE_UT, MagFit
from workbench.analysis.mag_heading import HeadingEvaluation, evaluate_heading
from workbench.analysis.mag_reference import ReferenceField
from workbench.angles import circular_mean
from workbench.calset import TriadCalibration
from workbench.errors import AnalysisError
from workbench.model import TriadModel
from workbench.session import Session

if TYPE_CHECKING:
    from workbench.analysis.mag_holdout import FreeQuality

MIN_POINTS = {"2d": 6, "2d-minmax": 6, "sphere": 8, "ellipsoid": 15, "algebraic": 15, "dip": 15, "attitude": 10}
STATIC_KINDS = ("static", "soak", "ramp")
ROTATING_KINDS = ("rate", "carousel")
_UNIT_FACTORS = {"gauss": 100.0, "milligauss": 0.1, "nT": 1e-3}  # µT per unit


@dataclass(frozen=True)
class MagPoints:
    """Points for a magnetometer fit (all arrays row-aligned).

    ``mag`` (N, 3) µT and ``accel`` (N, 3) m/s^2 (or None) in the body frame; ``attitude`` N
    body-to-reference rotations or None; ``frame`` names the reference (``"NED"`` when the
    table zero azimuth is known, else ``"table"``: level frame with x along the table zero);
    ``step`` (N,) the step index of each point; ``samples_per_point`` (N,); ``t`` (N,) s the mean
    sample time of each point; ``spike_t`` s the times of the raw samples left out as spikes
    (:mod:`mag_spikes`); ``gravity_ok`` (N,) bool the points whose specific force is gravity (None: all;
    by hand, the quasi-static ones: only they carry the dip constraint and the tilt spread).
    """

    mag: np.ndarray
    accel: np.ndarray | None = None
    attitude: Rotation | None = None
    frame: str | None = None
    step: np.ndarray | None = None
    samples_per_point: np.ndarray | None = None
    t: np.ndarray | None = None
    spike_t: np.ndarray | None = None
    gravity_ok: np.ndarray | None = None  # (N,) bool: points whose accel is gravity (hand-held: quasi-static)

    def __len__(self) -> int:
        return len(self.mag)


@dataclass(frozen=True)
class MagCalibration:
    """Everything :func:`calibrate` found: the fit, why it was chosen, quality, heading error (calibrated,
    raw = uncalibrated, and with the plain algebraic baseline fit), the points.

    Follows :class:`workbench.result.AnalysisResult`: :meth:`to_dict` (SI) and :meth:`summary` (lab units)."""

    fit: MagFit
    choice: mag_select.Choice
    quality: mag_quality.Quality
    heading: HeadingEvaluation | None
    raw_heading: HeadingEvaluation | None
    baseline: MagFit | None
    baseline_heading: HeadingEvaluation | None
    points: MagPoints
    warnings: tuple[str, ...]
    reference: ReferenceField | None = None
    free_quality: FreeQuality | None = None  # the truth-free figures of a hand-held fit
    motion: dict | None = None  # hand-held: mag time offset, gyro bias and gain (mag_motion.Timing.to_dict)

    def to_dict(self) -> dict:
        """JSON-ready result (SI, angles in rad unless the key says ``_deg``)."""
        return {"method": self.fit.method, "reason": self.choice.reason, "fit": self.fit.to_dict(),
                "quality": self.quality.to_dict(),
                "heading": None if self.heading is None else self.heading.to_dict(),
                "raw_heading": None if self.raw_heading is None else self.raw_heading.to_dict(),
                "baseline": None if self.baseline is None else self.baseline.to_dict(),
                "baseline_heading": None if self.baseline_heading is None else self.baseline_heading.to_dict(),
                "reference_field": None if self.reference is None else self.reference.to_dict(),
                "free_quality": None if self.free_quality is None else self.free_quality.to_dict(),
                "motion": self.motion, "n_points": len(self.points), "warnings": list(self.warnings)}

    def summary(self) -> list[str]:
        """Lines for people, in lab units: method and reason, hard iron µT, soft iron %, field norm µT,
        coverage and norm residual, dip and declination °, IMU-to-mag rotation mrad, heading error °,
        and the truth-free figures of a hand-held fit."""
        fit = self.fit
        off = fit.soft_iron - np.eye(3)
        finite = fit.soft_iron_sigma[np.isfinite(fit.soft_iron_sigma)]
        max_sig = float(finite.max()) if finite.size else float("nan")
        if fit.scale_fixed_by == "reference":
            norm = f"field norm: {units.fmt(fit.field_norm_ut, 'uT', 4)} (given: fixes the scale of I+M)"
        else:
            norm = (f"field norm: {units.pm(fit.field_norm_ut, fit.field_norm_sigma, 'uT', 4)} "
                    f"(scale fixed by {fit.scale_fixed_by})")
        lines = [f"method: {fit.method} ({self.choice.reason})",
                 "hard iron: " + ", ".join(f"{a} {units.pm(v, s, 'uT', 3)}"
                                           for a, v, s in zip("xyz", fit.bias, fit.bias_sigma)),
                 f"soft iron: largest |I+M - I| element {np.abs(off).max() * 100:.3g} %, "
                 f"largest sigma {units.fmt(max_sig, '%', 2)}",
                 norm,
                 f"coverage {self.quality.coverage:.0%} of the sphere, field-norm residual RMS "
                 f"{units.fmt(self.quality.norm_residual_rms_ut, 'uT', 3)}"]
        if fit.dip is not None:
            lines.append(f"dip: {units.pm(fit.dip, fit.dip_sigma, 'deg', 5)}")
        if fit.declination is not None:
            lines.append("declination from the reference x axis: "
                         f"{units.pm(fit.declination, fit.declination_sigma, 'deg', 4)}")
        if fit.alignment is not None:
            lines.append("IMU-to-mag rotation: " + ", ".join(
                f"{a} {units.pm(v, s, 'mrad', 3)}" for a, v, s in zip("xyz", fit.alignment, fit.alignment_sigma)))
        if self.heading is not None:
            base = (f", plain algebraic fit {np.degrees(self.baseline_heading.rms):.3g}°"
                    if self.baseline_heading is not None else "")
            lines.append(f"heading error vs table (tilt from {self.heading.tilt_source}): "
                         f"RMS {np.degrees(self.heading.rms):.3g}° "
                         f"(uncalibrated {np.degrees(self.raw_heading.rms):.3g}°{base})")
        if self.free_quality is not None:
            lines += self.free_quality.lines(fit.method)
        return lines


def points_from_session(session: Session, block_deg: float = 1.0, reject_spikes: bool = True) -> MagPoints:
    """Fit points from a session with magnetometer columns (see the module docstring).

    Static steps give one point each (their mean); rate and carousel steps are cut into
    blocks of at most ``block_deg`` degrees of table rotation (using the ``table_angle``
    column when present, else the commanded rate). Index moves are skipped. With
    ``reject_spikes``, raw samples that are spikes (:func:`mag_spikes.spike_mask`) are left
    out of the means; their times are in ``spike_t``.
    """
    if not session.has_mag:
        raise AnalysisError(f"{session.name}: samples have no magnetometer columns mx, my, mz")
    frame = "NED" if session.site.table_zero_azimuth is not None else "table"
    used = [(st, session.step_samples(st.index)) for st in session.steps if st.kind in STATIC_KINDS + ROTATING_KINDS]
    used = [(st, df) for st, df in used if not df.empty]
    raw = [df[["mx", "my", "mz"]].to_numpy(float) for _, df in used]
    spikes = (mag_spikes.spike_mask([mag_spikes.running_median_residual(m) for m in raw]) if reject_spikes
              else [np.zeros(len(m), bool) for m in raw])
    mags, accs, rots, steps, counts, times, spike_t = [], [], [], [], [], [], []
    for (st, df), m, spike in zip(used, raw, spikes):
        spike_t.append(df["t"].to_numpy(float)[spike])
        df, m = df[~spike], m[~spike]
        if df.empty:
            continue
        a = df[["ax", "ay", "az"]].to_numpy(float)
        if st.kind in STATIC_KINDS:
            angle = circular_mean(df["table_angle"].to_numpy(float)) if "table_angle" in df else st.table_angle
            groups = [(np.arange(len(df)), angle)]
        else:
            t = df["t"].to_numpy(float)
            ang = np.unwrap(df["table_angle"].to_numpy(float) if "table_angle" in df
                            else st.table_angle + st.table_rate * (t - st.t_start))
            block = np.floor(np.abs(ang - ang[0]) / np.radians(block_deg)).astype(int)
            groups = [(g, float(np.mean(ang[g]))) for g in (np.flatnonzero(block == k) for k in np.unique(block))]
        for g, angle in groups:
            mags.append(m[g].mean(axis=0))
            accs.append(a[g].mean(axis=0))
            times.append(float(df["t"].to_numpy(float)[g].mean()))
            rot = session.attitude(st, angle) if frame == "NED" else session.table_attitude(st, angle)
            rots.append(rot)
            steps.append(st.index)
            counts.append(len(g))
    if not mags:
        raise AnalysisError(f"{session.name}: no static or rotating step with samples for a magnetometer fit")
    return MagPoints(np.array(mags), np.array(accs), Rotation.concatenate(rots), frame, np.array(steps),
                     np.array(counts), np.array(times), np.concatenate(spike_t) if spike_t else np.zeros(0))


def check_points(mag: np.ndarray, method: str, source: str = "magnetometer data") -> None:
    """Reject input no fit can trust: NaN, too few points, units that are not µT (raises AnalysisError)."""
    mag = np.asarray(mag, float)
    if mag.ndim != 2 or mag.shape[1] != 3:
        raise AnalysisError(f"{source}: expected an (N, 3) array of µT, got shape {mag.shape}")
    bad = ~np.isfinite(mag).all(axis=1)
    if bad.any():
        raise AnalysisError(f"{source}: NaN or infinite value in {int(bad.sum())} point(s), first at row "
                            f"{int(np.argmax(bad))}; remove or repair them")
    need = MIN_POINTS.get(method, max(MIN_POINTS.values()))
    if len(mag) < need:
        raise AnalysisError(f"{source}: {len(mag)} points, the {method} fit needs at least {need}")
    _check_units(float(np.median(np.linalg.norm(mag - np.median(mag, axis=0), axis=1))), source)


def _check_units(size: float, source: str) -> None:
    """Raise if the cloud's size (median distance from its centre, µT; independent of the hard
    iron) only makes sense in another unit (gauss, milligauss, nT)."""
    lo, hi = FIELD_RANGE_UT
    if lo / 3 <= size <= hi * 3:
        return
    for unit, f in _UNIT_FACTORS.items():
        if lo <= size * f <= hi * 3:
            raise AnalysisError(f"{source}: field size {size:.4g} where µT is declared looks like {unit} "
                                f"({size * f:.4g} µT after conversion); convert to µT")


def _down(points: MagPoints) -> np.ndarray | None:
    if points.accel is not None:
        return mag_attitude.down_direction(points.accel)
    if points.attitude is not None:
        return points.attitude.inv().apply(np.array([0.0, 0.0, 1.0]))
    return None


def fit_method(method: str, points: MagPoints, down: np.ndarray | None, field_norm_ut, robust: bool | str,
               notes: tuple[str, ...] = ()) -> MagFit:
    """Fit one named estimator to ``points`` (``down`` (N, 3) unit down directions or None; see :func:`calibrate`).

    A 3D fit on planar points and a 2D fit on 3D points are refused (AnalysisError naming the cloud's thickness).
    """
    mag = points.mag
    flat = mag_quality.thickness(mag)
    if method in ("sphere", "ellipsoid", "algebraic", "dip", "attitude") and flat < mag_quality.FLAT_LIMIT_UT:
        raise AnalysisError(f"{method} fit: all points lie in one plane (cloud {flat:.3g} µT thick): a 3D fit needs "
                            "tilted positions; use method '2d' for level data")
    if method in ("2d", "2d-minmax") and flat >= mag_quality.FLAT_LIMIT_UT:
        raise AnalysisError(f"{method} fit: the points are not level (cloud {flat:.3g} µT thick >= "
                            f"{mag_quality.FLAT_LIMIT_UT:g} µT): a 2D fit would put the tilt into the hard iron; "
                            "use method 'auto' or a 3D method")
    if method in ("2d", "2d-minmax"):
        dmean = down.mean(axis=0) if down is not None else np.array([0.0, 0.0, 1.0])
        return (mag_fit2d.fit_2d(mag, dmean, robust) if method == "2d" else mag_fit2d.fit_2d_minmax(mag, dmean, robust))
    if method == "sphere":
        return mag_ellipsoid.fit_sphere(mag, field_norm_ut, robust, notes)
    if method == "ellipsoid":
        return mag_ellipsoid.fit_ellipsoid(mag, field_norm_ut, robust, notes)
    if method == "algebraic":
        return mag_ellipsoid.fit_algebraic_plain(mag, field_norm_ut)
    if method == "dip":
        if points.accel is None:
            raise AnalysisError("dip fit: needs accelerometer data")
        return mag_attitude.fit_dip(mag, points.accel, field_norm_ut, robust, notes, points.gravity_ok)
    if points.attitude is None:
        raise AnalysisError("attitude fit: needs the attitude of every point (table angles)")
    return mag_attitude.fit_attitude(mag, points.attitude, field_norm_ut, robust, notes)


def calibrate(points: MagPoints, method: str = "auto", robust: bool | str = False, field_norm_ut: float | None = None,
              declination: float | None = None, baseline: bool = True, accel_model: TriadModel | None = None,
              reference: ReferenceField | None = None, source: str = "magnetometer data",
              data: str | None = None, choice: mag_select.Choice | None = None,
              accel_compensated: bool = False) -> MagCalibration:
    """Calibrate a magnetometer from ``points``.

    Parameters
    ----------
    method : one of :data:`mag_select.METHODS`; ``auto`` chooses (reason reported)
    robust : reject outliers before the final least-squares fit (True), never (False), or when
        the residuals are heavy-tailed (``"auto"``, :func:`mag_fit.heavy_tails`)
    field_norm_ut : reference field magnitude µT (the site's field), fixes the scale of ``I + M``;
        None uses ``det(I + M) = 1`` and reports the fitted norm
    declination : rad, field azimuth from the reference x axis for the heading error; None uses
        the attitude fit's estimate or, for other methods, the mean offset
    baseline : also fit the plain algebraic ellipsoid (3D data) for comparison
    accel_model : the accelerometer's calibration; its compensation is applied to ``points.accel``
        first (an uncalibrated accelerometer's bias tilts the gravity direction: 20 mg ~ 1.1°), unless
        ``accel_compensated`` (the caller applied it already, e.g. before tracking gravity through a motion)
    reference : a geomagnetic model's field at the site (:mod:`mag_reference`): the fitted norm
        (when estimated) and dip are checked against it (warnings)
    data : a phrase naming the data the points come from; it leads the reason of the choice
    choice : the estimator already chosen, with its reason (overrides ``method``)

    The heading error is evaluated when the attitude is known, with the tilt from the
    calibrated accelerometer when ``accel_model`` is given, else from the table attitude (so
    that it measures the magnetometer calibration, not the accelerometer's errors).
    """
    if method not in mag_select.METHODS:
        raise AnalysisError(f"unknown magnetometer method {method!r} (known: {', '.join(mag_select.METHODS)})")
    check_points(points.mag, method if method != "auto" else "2d", source)
    if points.accel is not None and not np.isfinite(points.accel).all():
        raise AnalysisError(f"{source}: NaN or infinite accelerometer value")
    if accel_model is not None and points.accel is not None and not accel_compensated:
        points = replace(points, accel=accel_model.compensate(points.accel))
    down = _down(points)
    flat = mag_quality.thickness(points.mag)
    raw_cov = mag_quality.sphere_coverage(points.mag - points.mag.mean(axis=0))
    spread = None
    if points.accel is not None or points.attitude is not None:
        spread = mag_quality.gravity_spread(down if points.gravity_ok is None else down[points.gravity_ok])
    if choice is None and method == "auto":
        choice = mag_select.choose(flat, raw_cov, spread, points.attitude is not None)
    elif choice is None:
        choice = mag_select.Choice(method, "chosen by the user")
    if data:
        choice = mag_select.Choice(choice.method, f"{data}; {choice.reason}")
    check_points(points.mag, choice.method, source)
    notes = ()
    if choice.method == "dip" and accel_model is None:
        notes = ("dip fit with the uncalibrated accelerometer: its bias tilts the gravity direction (20 mg ~ 1.1°) "
                 "and biases the fit; give the accelerometer calibration",)
    fit = fit_method(choice.method, points, down, field_norm_ut, robust, notes)
    quality = mag_quality.assess(fit, points.mag, down, field_norm_ut)
    head = raw_head = base = base_head = None
    if points.attitude is not None:
        tilt, hdown = (("calibrated accelerometer", down) if accel_model is not None and points.accel is not None
                       else ("table", points.attitude.inv().apply(np.array([0.0, 0.0, 1.0]))))
        decl = declination if declination is not None else fit.declination
        head = evaluate_heading(fit.compensate(points.mag), hdown, points.attitude, decl, tilt)
        known = None if head.declination_estimated else head.declination
        raw_head = evaluate_heading(points.mag, hdown, points.attitude, known, tilt)
    if baseline and not choice.method.startswith("2d") and len(points) >= MIN_POINTS["algebraic"]:
        try:
            base = mag_ellipsoid.fit_algebraic_plain(points.mag, field_norm_ut)
        except AnalysisError as exc:  # the baseline failing is itself a finding, not an error of ours
            quality = replace(quality, warnings=(*quality.warnings, f"plain algebraic baseline: {exc}"))
        if base is not None and head is not None:
            base_head = evaluate_heading(base.compensate(points.mag), hdown, points.attitude, known, tilt)
    ref_notes = mag_reference.compare(fit, reference) if reference is not None else []
    warnings = tuple(dict.fromkeys((*fit.warnings, *quality.warnings, *ref_notes, *outlier_notes(points, fit))))
    return MagCalibration(fit, choice, quality, head, raw_head, base, base_head, points, warnings, reference)


def _times(t: np.ndarray) -> str:
    shown = ", ".join(f"{v:.2f}" for v in t[:8])
    return f"t = {shown}{f' ... (+{len(t) - 8} more)' if len(t) > 8 else ''} s"


def outlier_notes(points: MagPoints, fit: MagFit) -> list[str]:
    """Lines saying how many raw samples were spikes and how many fit points outliers, and when."""
    out = []
    if points.spike_t is not None and len(points.spike_t):
        out.append(f"{len(points.spike_t)} magnetometer samples left out as spikes (> {mag_spikes.REJECT_SIGMA:g} "
                   f"noise sigma from the running median): {_times(np.sort(points.spike_t))}")
    if fit.rejected and points.t is not None:
        out.append(f"{len(fit.rejected)} of {len(points)} fit points rejected as outliers: "
                   f"{_times(np.sort(points.t[list(fit.rejected)]))}")
    return out


def triad_calibration(fit: MagFit) -> TriadCalibration:
    """The calibration set's ``mag`` block of a fit (hard iron µT, ``M`` = soft iron - I, field norm, sigmas)."""
    sigma = {"bias": fit.bias_sigma, "scale_misalignment": fit.soft_iron_sigma}
    return TriadCalibration(fit.model, sigma, float(fit.field_norm_ut),
                            None if not np.isfinite(fit.field_norm_sigma) else float(fit.field_norm_sigma))
