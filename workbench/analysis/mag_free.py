"""Magnetometer calibration from a unit turned by hand (``free`` steps, or turns declared ``by_hand``): no table,
gravity from the unit.

On a ``free`` step nothing but the unit's own sensors knows the attitude, so the fit never uses a
table angle or mount. The points (:func:`free_points`) are block means (``block_s``) of the
magnetometer and the accelerometer; a block counts as quasi-static (its specific force is gravity)
when its norm is within ``QUASI_STATIC_TOL`` of the local gravity (the median norm over the still
stretches the stationarity detector finds, :mod:`workbench.analysis.stationarity`, else over all
blocks). Only quasi-static blocks are fitted: the dip constraint (the angle between field and
gravity is constant, :func:`workbench.analysis.mag_attitude.fit_dip`) then fixes hard iron, soft
iron and the magnetometer-to-IMU rotation together.

:func:`holdout_quality` gives the truth-free figures printed with every hand-held fit: the RMS of
the calibrated field norm (% of the fitted norm) and the spread (standard deviation, rad) of the
field-to-gravity angle, on all points and held out (fitted on the first half in time, evaluated
on the second), for the fit and for a plain 10-coefficient algebraic ellipsoid on the same points.

Public: :data:`QUASI_STATIC_TOL`, :class:`FreeData`, :func:`free_points`, :class:`FitFigures`,
:class:`FreeQuality`, :func:`figures_of`, :func:`holdout_quality`, :func:`calibrate_free`,
:func:`split_half_scale`, :func:`scaled_sigmas`.

Sigmas: besides the residuals' autocorrelation (:mod:`workbench.analysis.mag_fit`), the fits of the two
halves in time must agree within their sigmas; when they do not (model misfit: a hand-held record's
residuals depend on where the hand took the unit), every sigma is scaled by their rms z
(:func:`split_half_scale`), and a warning says so.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from workbench.analysis import mag_ellipsoid, mag_quality, mag_spikes, stationarity
from workbench.analysis.mag_attitude import down_direction
from workbench.analysis.mag_fit import MagFit
from workbench.analysis.mag_quality import gravity_spread
from workbench.analysis.mag_select import Choice
from workbench.analysis.magnetometer import MIN_POINTS, MagCalibration, MagPoints, calibrate, fit_method
from workbench.errors import AnalysisError
from workbench.session import Session

QUASI_STATIC_TOL = 0.03  # relative deviation of the block's |f| from local gravity (3 %: ~1.7° worst-case tilt error)
BLOCK_S = 0.05  # s, length of one fit point's block
MIN_STILL_STRETCHES = 6  # still stretches (orientations) for a fit on still blocks alone
MIN_STILL_TILT = float(np.radians(30.0))  # rad, spread of their gravity directions


@dataclass(frozen=True)
class FreeData:
    """Points of the ``free`` steps: ``mag`` (N, 3) µT, ``accel`` (N, 3) m/s^2 block means, ``t`` (N,) s,
    ``step`` (N,), ``quasi_static`` (N,) bool, ``still`` (N,) bool (every sample of the block still); ``gravity`` m/s^2 the local |f| used;
    ``still_stretches`` the number found, ``still_s`` their total length, ``spike_t`` s."""

    mag: np.ndarray
    accel: np.ndarray
    t: np.ndarray
    step: np.ndarray
    quasi_static: np.ndarray
    still: np.ndarray
    gravity: float
    still_stretches: int
    still_s: float
    steps: tuple[int, ...]
    spike_t: np.ndarray
    free: bool = True  # all of them of kind free (else turns declared by hand)

    @property
    def uses_still(self) -> bool:
        """Whether the still blocks alone carry the fit: at least :data:`MIN_STILL_STRETCHES` stretches whose
        gravity directions span more than :data:`MIN_STILL_TILT` (else the quasi-static blocks do)."""
        if self.still_stretches < MIN_STILL_STRETCHES or self.still.sum() < 15:
            return False
        return gravity_spread(down_direction(self.accel[self.still])) > MIN_STILL_TILT

    def fit_mask(self) -> np.ndarray:
        """(N,) the blocks fitted: the still ones when they suffice (:attr:`uses_still`), else the quasi-static ones."""
        return self.still if self.uses_still else self.quasi_static

    def describe(self) -> str:
        """One phrase naming the data: steps, blocks fitted and why, still stretches."""
        names = ", ".join(str(s) for s in self.steps)
        head = (f"{'free step' if self.free else 'step'}{'s' if len(self.steps) > 1 else ''} {names} "
                f"(by hand, no table attitude), "
                f"{self.still_stretches} still stretch(es) ({self.still_s:.1f} s): ")
        head += f"all {len(self.t)} {BLOCK_S * 1e3:g}-ms blocks carry the field norm, "
        if self.uses_still:
            return head + f"the {int(self.still.sum())} of the still stretches gravity"
        return head + (f"too few still orientations: the {int(self.quasi_static.sum())} quasi-static ones "
                       f"(|f| within {QUASI_STATIC_TOL:.0%} of {self.gravity:.3f} m/s²) gravity")


def hand_steps(session: Session) -> list:
    """The steps whose attitude only the unit's own sensors know: kind ``free``, or a turn declared ``by_hand``
    (an imported hand-made turn: its table angle is a guess, never a measurement)."""
    return [st for st in session.steps if st.kind == "free" or bool(st.extra.get("by_hand"))]


def free_points(session: Session, block_s: float = BLOCK_S, reject_spikes: bool = True) -> FreeData:
    """Block means of the magnetometer and accelerometer on the session's ``free`` steps.

    Samples the import flagged (repeated or saturated) are left out of the means; with
    ``reject_spikes``, magnetometer spikes in the still stretches too (:mod:`mag_spikes`). Raises AnalysisError when
    there is no free step or no block with samples.
    """
    steps = hand_steps(session)
    if not steps:
        raise AnalysisError(f"{session.name}: no free step (nor a step turned by hand)")
    if not session.has_mag:
        raise AnalysisError(f"{session.name}: samples have no magnetometer columns mx, my, mz")
    frames = [(st, session.step_samples(st.index)) for st in steps]
    frames = [(st, df) for st, df in frames if len(df)]
    raw = [df[["mx", "my", "mz"]].to_numpy(float) for _, df in frames]
    mags, accs, ts, labels, norms_still, spike_t, blk_still = [], [], [], [], [], [], []
    n_still, still_s = 0, 0.0
    for (st, df), m in zip(frames, raw):
        t = df["t"].to_numpy(float)
        spike = np.zeros(len(df), bool)
        a = df[["ax", "ay", "az"]].to_numpy(float)
        g = df[["gx", "gy", "gz"]].to_numpy(float)
        ok_m = session.good("mag", st.index) & ~spike
        ok_a = session.good("accel", st.index)
        still = np.zeros(len(df), bool)
        if len(df) >= max(3, int(0.5 * session.sample_rate_hz)):
            found = stationarity.detect(g, a, session.sample_rate_hz)
            still = found.still
            n_still += len(found.stretches)
            still_s += float(still.sum() / session.sample_rate_hz)
            if still.any():
                norms_still.append(np.linalg.norm(a[still & ok_a], axis=1))
        # raw-sample spikes only where the unit is still: in motion a running median cannot tell a spike from the
        # hand's turn (the robust fit's outlier rejection of points covers those)
        if reject_spikes and still.sum() > mag_spikes.WINDOW:
            idx = np.flatnonzero(still & ok_m)
            hit = mag_spikes.spike_mask([mag_spikes.running_median_residual(m[idx])])[0]
            spike[idx[hit]] = True
            ok_m[idx[hit]] = False
        spike_t.append(t[spike])
        block = np.floor((t - t[0]) / block_s).astype(int)
        for k in np.unique(block):
            sel = block == k
            sm, sa = sel & ok_m, sel & ok_a
            if not sm.any() or not sa.any():
                continue
            mags.append(m[sm].mean(axis=0))
            accs.append(a[sa].mean(axis=0))
            ts.append(float(t[sel].mean()))
            labels.append(st.index)
            blk_still.append(bool(still[sel].all()))
    if not mags:
        raise AnalysisError(f"{session.name}: free steps have no samples usable for a magnetometer fit")
    acc = np.array(accs)
    norm = np.linalg.norm(acc, axis=1)
    still_norms = np.concatenate(norms_still) if norms_still else np.zeros(0)
    grav = float(np.median(still_norms)) if len(still_norms) else float(np.median(norm))
    quasi = np.abs(norm / grav - 1.0) < QUASI_STATIC_TOL
    return FreeData(np.array(mags), acc, np.array(ts), np.array(labels), quasi, np.array(blk_still), grav, n_still, still_s,
                    tuple(st.index for st, _ in frames), np.concatenate(spike_t) if spike_t else np.zeros(0),
                    all(st.kind == "free" for st, _ in frames))


@dataclass(frozen=True)
class FitFigures:
    """Truth-free figures of one calibration on a set of points: field-norm RMS (fraction of the norm)
    and the standard deviation of the field-to-gravity angle (rad), in sample and held out."""

    norm_rms: float
    angle_spread: float
    norm_rms_held_out: float
    angle_spread_held_out: float

    def to_dict(self) -> dict:
        return {"field_norm_rms_pct": 100 * self.norm_rms, "angle_spread_deg": float(np.degrees(self.angle_spread)),
                "field_norm_rms_pct_held_out": 100 * self.norm_rms_held_out,
                "angle_spread_deg_held_out": float(np.degrees(self.angle_spread_held_out))}


@dataclass(frozen=True)
class FreeQuality:
    """The figures of the fit and of the plain algebraic ellipsoid on the same points (``baseline``,
    None if it fails), the number of points and where the halves split (``split_t`` s)."""

    fit: FitFigures
    baseline: FitFigures | None
    n_points: int
    split_t: float
    notes: tuple[str, ...] = ()
    series: dict | None = None  # per point: t s; norm (fraction) and angle rad (NaN without gravity) per fit

    def to_dict(self) -> dict:
        return {"fit": self.fit.to_dict(), "plain_ellipsoid": None if self.baseline is None else self.baseline.to_dict(),
                "n_points": self.n_points, "split_t_s": self.split_t, "notes": list(self.notes)}

    def lines(self, method: str) -> list[str]:
        """Lines for people (%, °)."""
        def row(name, f):
            return (f"{name}: field-norm RMS {100 * f.norm_rms:.2f} % (held out {100 * f.norm_rms_held_out:.2f} %), "
                    f"field-to-gravity angle spread {np.degrees(f.angle_spread):.2f}° "
                    f"(held out {np.degrees(f.angle_spread_held_out):.2f}°)")
        out = [f"hand-held quality, no truth needed ({self.n_points} points fitted; held out = fitted before "
               f"t = {self.split_t:.1f} s, judged after):", "  " + row(method, self.fit)]
        out.append("  " + (row("plain 10-coefficient ellipsoid", self.baseline) if self.baseline is not None
                           else "plain 10-coefficient ellipsoid: " + "; ".join(self.notes)))
        return out


def point_values(fit: MagFit, mag: np.ndarray, down: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per point: calibrated field norm relative to the fitted norm minus 1 (N,), and the angle (N,) rad
    between the calibrated field and the down direction, for raw points ``mag`` (N, 3) µT and unit down
    directions ``down`` (N, 3), IMU frame."""
    h = fit.compensate(mag)
    hn = np.linalg.norm(h, axis=1)
    return hn / fit.field_norm_ut - 1.0, np.arccos(np.clip(np.sum(h * down, axis=1) / hn, -1.0, 1.0))


def figures_of(fit: MagFit, mag: np.ndarray, down: np.ndarray, gravity_ok: np.ndarray | None = None) -> tuple[float, float]:
    """(field-norm RMS as a fraction of the fitted norm over all points, std of the field-to-gravity angle rad
    over the points whose specific force is gravity, ``gravity_ok`` (N,) bool, default all) of ``fit`` on raw
    points ``mag`` (N, 3) µT with unit down directions ``down`` (N, 3), IMU frame."""
    norm, angle = point_values(fit, mag, down)
    ok = np.ones(len(mag), bool) if gravity_ok is None else gravity_ok
    return float(np.sqrt(np.mean(norm**2))), float(np.std(angle[ok])) if ok.any() else float("nan")


Fitter = Callable[[np.ndarray], MagFit]  # fits the points selected by a (N,) bool mask


def _halves(t: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    split = float(np.median(t))
    return split, t <= split, t > split


def held_out(fitter: Fitter, mag: np.ndarray, down: np.ndarray, gravity_ok: np.ndarray, train: np.ndarray,
             test: np.ndarray) -> tuple[float, float]:
    """:func:`figures_of` on the ``test`` points of a fit to the ``train`` points (masks (N,))."""
    return figures_of(fitter(train), mag[test], down[test], gravity_ok[test])


def holdout_quality(fitter: Fitter, fit: MagFit, mag: np.ndarray, accel: np.ndarray, t: np.ndarray,
                    gravity_ok: np.ndarray) -> FreeQuality:
    """Figures of ``fit`` (fitted on all points) and of ``fitter`` refitted on the first half in time and
    judged on the second; the same for the plain algebraic ellipsoid (see the module docstring).
    ``mag`` (N, 3) µT, ``accel`` (N, 3) m/s^2, ``t`` (N,) s of the points, ``gravity_ok`` (N,) bool the
    points whose specific force is gravity (the angle is judged on them)."""
    down = down_direction(accel)
    split, first, second = _halves(t)
    notes: list[str] = []
    series: dict = {"t": t}

    def figures(name: str, fit_all: MagFit, one: Fitter) -> FitFigures:
        a, b = figures_of(fit_all, mag, down, gravity_ok)
        c, d = held_out(one, mag, down, gravity_ok, first, second)
        norm, angle = point_values(fit_all, mag, down)
        series[f"{name}_norm"], series[f"{name}_angle"] = norm, np.where(gravity_ok, angle, np.nan)
        return FitFigures(a, b, c, d)

    ours = figures("fit", fit, fitter)
    try:
        base = figures("plain", mag_ellipsoid.fit_algebraic_plain(mag),
                       lambda sel: mag_ellipsoid.fit_algebraic_plain(mag[sel]))
    except AnalysisError as exc:
        base = None
        notes.append(f"failed ({exc})")
    return FreeQuality(ours, base, len(mag), split, tuple(notes), series)


def _choose(fitters: dict[str, Fitter], mag: np.ndarray, down: np.ndarray, gravity_ok: np.ndarray,
            t: np.ndarray) -> Choice:
    """The estimator whose field-to-gravity angle spread, held out both ways (fit on one half in time, judge
    on the other), is the smaller; the constant-dip fit on a tie. The reason gives the figures."""
    _, first, second = _halves(t)
    scores = {}
    for name, f in fitters.items():
        try:
            scores[name] = np.mean([held_out(f, mag, down, gravity_ok, a, b)[1] for a, b in ((first, second),
                                                                                              (second, first))])
        except AnalysisError:
            continue
    if not scores:
        raise AnalysisError("hand-held magnetometer fit: neither the constant-dip fit nor the ellipsoid fits "
                            "one half of the record")
    best = min(scores, key=lambda k: (scores[k], k != "dip"))
    shown = ", ".join(f"{k} {np.degrees(v):.2f}°" for k, v in scores.items())
    why = ("constant-dip fit: hard/soft iron and the mag-to-IMU rotation" if best == "dip" else
           "ellipsoid: the halves do not agree on a mag-to-IMU rotation, so it is not estimated (symmetric soft iron)")
    return Choice(best, f"field-to-gravity angle spread held out both ways (half to half): {shown}; {why}")


MIN_CLOUD_UT = 10.0  # µT, principal standard deviation of the raw cloud along a direction the field must have turned
MIN_DIP_TILT = float(np.radians(30.0))  # rad, spread of the gravity directions the dip fit needs


def _candidates(name: str, data: FreeData, down: np.ndarray) -> list[str] | None:
    """The estimators the data support (None: leave it to the planar choice, a level turn). The field must
    have turned: the raw cloud's second principal standard deviation at least :data:`MIN_CLOUD_UT`; a 3D fit
    needs it out of every plane too (the third), then the constant-dip fit when gravity takes many directions
    and the ellipsoid when the field directions cover enough of the sphere. Else AnalysisError naming the data."""
    centred = data.mag - data.mag.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False) / np.sqrt(len(centred))
    cover = mag_quality.sphere_coverage(centred)
    spread = gravity_spread(down[data.fit_mask()])
    figures = (f"raw cloud {sv[0]:.3g} x {sv[1]:.3g} x {sv[2]:.3g} µT (principal sigmas), field directions "
               f"{cover:.0%} of the sphere, gravity directions within {np.degrees(spread):.0f}°")
    if sv[1] < MIN_CLOUD_UT:
        raise AnalysisError(f"{name}: {data.describe()}: the unit was not turned enough for a magnetometer fit "
                            f"({figures}; need {MIN_CLOUD_UT:g} µT in two directions); turn it through a full circle "
                            "(2D) or tumble it through many orientations (3D)")
    if sv[2] < mag_quality.FLAT_LIMIT_UT:
        return None  # a level turn: the planar (2D) choice
    out = []
    if sv[2] >= MIN_CLOUD_UT and spread > MIN_DIP_TILT:
        out.append("dip")
    if sv[2] >= MIN_CLOUD_UT and cover >= mag_quality.COVERAGE_FOR_ELLIPSOID:
        out.append("ellipsoid")
    if not out:
        raise AnalysisError(f"{name}: {data.describe()}: {figures}: a turn about one axis, not level enough for a "
                            f"2D fit (out of plane {sv[2]:.3g} µT >= {mag_quality.FLAT_LIMIT_UT:g}) and not "
                            f"tumbled enough for a 3D one (needs {MIN_CLOUD_UT:g} µT out of every plane and gravity "
                            f"over {np.degrees(MIN_DIP_TILT):.0f}° or {mag_quality.COVERAGE_FOR_ELLIPSOID:.0%} of the "
                            "sphere); tumble the unit about several axes")
    return out


def calibrate_free(session: Session, method: str = "auto", robust: bool | str = False,
                   field_norm_ut: float | None = None, accel_model=None, reference=None) -> MagCalibration:
    """Calibrate the magnetometer from the session's ``free`` steps (see the module docstring).

    Every block carries the field-norm constraint; the blocks whose specific force is gravity (the still
    ones when they suffice, else the quasi-static ones) also carry the dip constraint and judge the angle.
    ``auto`` chooses between the constant-dip fit and the ellipsoid by their held-out angle spread
    (:func:`_choose`); the reason names the data and the figures. The result carries the
    :class:`FreeQuality` figures. ``accel_model`` compensates the accelerometer first.
    """
    data = free_points(session, reject_spikes=robust is not False)
    q = data.fit_mask()
    if q.sum() < MIN_POINTS["dip"]:
        raise AnalysisError(f"{session.name}: {data.describe()}: too few points with gravity for a fit "
                            f"(need {MIN_POINTS['dip']}); hold the unit still or turn it more slowly")
    points = MagPoints(data.mag, data.accel, None, None, data.step, None, data.t, data.spike_t, q)
    accel = data.accel if accel_model is None else accel_model.compensate(data.accel)
    down = down_direction(accel)

    cache: dict = {}

    def fitter(name: str) -> Fitter:
        def fit(sel: np.ndarray) -> MagFit:  # each half is fitted once (choice, quality, sigma check)
            key = (name, sel.tobytes())
            if key not in cache:
                cache[key] = fit_method(name, MagPoints(data.mag[sel], accel[sel], gravity_ok=q[sel]), down[sel],
                                        field_norm_ut, robust)
            return cache[key]
        return fit

    choice = None
    if method == "auto" and (names := _candidates(session.name, data, down)) is not None:
        choice = _choose({m: fitter(m) for m in names}, data.mag, down, q, data.t)
    cal = calibrate(points, method=method, robust=robust, field_norm_ut=field_norm_ut, accel_model=accel_model,
                    reference=reference, source=session.name, data=data.describe(), choice=choice)
    quality = holdout_quality(fitter(cal.fit.method), cal.fit, data.mag, accel, data.t, q)
    _, first, second = _halves(data.t)
    try:
        half_a, half_b = fitter(cal.fit.method)(first), fitter(cal.fit.method)(second)
        scales = split_half_scale(half_a, half_b)
    except AnalysisError:
        scales = {}
    warnings = cal.warnings
    fit = cal.fit
    if any(k > 1.0 for k, _ in scales.values()):
        fit = scaled_sigmas(fit, {g: k for g, (k, _) in scales.items()})
        shown = ", ".join(f"{g} x{k:.2f} (rms z {z:.2f})" for g, (k, z) in scales.items() if k > 1.0)
        if scales.get("hard iron", (1.0, 0.0))[0] > 1.0:
            drift = half_b.bias - half_a.bias
            shown += f"; the hard iron moves by ({', '.join(f'{v:+.2f}' for v in drift)}) µT from the first half to the second"
        warnings = (*warnings, f"sigmas scaled where the fits of the two halves in time differ by more than their "
                               f"sigmas (model misfit or correlated residuals): {shown}")
    return replace(cal, fit=fit, warnings=warnings, free_quality=quality)


GROUPS = ("hard iron", "soft iron", "field norm")


def _coefficients(fit: MagFit) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per group of :data:`GROUPS`: the fit's coefficients (µT or dimensionless) and their sigmas."""
    return {"hard iron": (fit.bias, fit.bias_sigma), "soft iron": (fit.soft_iron.ravel(), fit.soft_iron_sigma.ravel()),
            "field norm": (np.array([fit.field_norm_ut]), np.array([fit.field_norm_sigma]))}


def split_half_scale(a: MagFit, b: MagFit) -> dict[str, tuple[float, float]]:
    """Per group of :data:`GROUPS`: (scale, rms z) from the fits of the two halves of a record, with
    ``z = (c_a - c_b) / sqrt(s_a^2 + s_b^2)`` over the coefficients both observe and ``scale = max(1, rms z)``:
    what the full fit's sigmas of that group need for the halves to agree (a correct model and white
    residuals give rms z ~ 1 and leave them alone)."""
    out = {}
    for g, ((ca, sa), (cb, sb)) in zip(GROUPS, zip(_coefficients(a).values(), _coefficients(b).values())):
        ok = np.isfinite(sa) & np.isfinite(sb) & (np.hypot(sa, sb) > 0)
        if ok.any():
            rms = float(np.sqrt(np.mean(((ca - cb)[ok] / np.hypot(sa, sb)[ok]) ** 2)))
            out[g] = (max(1.0, rms), rms)
    return out


def scaled_sigmas(fit: MagFit, k: dict[str, float]) -> MagFit:
    """``fit`` with the sigmas of each group of :data:`GROUPS` multiplied by ``k[group]`` (1 if absent); dip,
    declination and alignment take the soft iron's."""
    ks = k.get("soft iron", 1.0)

    def mul(x):
        return None if x is None else x * ks
    return replace(fit, bias_sigma=fit.bias_sigma * k.get("hard iron", 1.0), soft_iron_sigma=fit.soft_iron_sigma * ks,
                   field_norm_sigma=fit.field_norm_sigma * k.get("field norm", 1.0), dip_sigma=mul(fit.dip_sigma),
                   declination_sigma=mul(fit.declination_sigma), alignment_sigma=mul(fit.alignment_sigma))
