"""Magnetometer calibration from a unit turned by hand (``free`` steps, or turns declared ``by_hand``): no table,
gravity from the unit.

On such a step nothing but the unit's own sensors knows the attitude, so the fit never uses a table
angle or mount. The points (:func:`free_points`) are block means (``block_s``) of the magnetometer
and the accelerometer. Every block carries the field-norm constraint; the blocks whose specific
force is gravity carry the dip constraint too (the angle between field and gravity is constant,
:func:`workbench.analysis.mag_attitude.fit_dip`, which then fixes hard iron, soft iron and the
magnetometer-to-IMU rotation together): the still stretches of the stationarity detector
(:mod:`workbench.analysis.stationarity`) when they suffice, else the blocks whose gravity direction is
tracked through the motion with the gyro (:mod:`workbench.analysis.mag_motion`: the hand's accelerations
averaged out; the magnetometer's time offset to the gyro fitted and corrected first), else the
quasi-static blocks (norm within ``QUASI_STATIC_TOL`` of local gravity).

:func:`calibrate_free` checks that the data support a fit (:func:`_candidates`), chooses between the
constant-dip fit and the ellipsoid by their held-out field-to-gravity angle spread (:func:`_choose`),
and attaches the truth-free quality figures and the sigmas from the record's blocks in time
(:mod:`workbench.analysis.mag_holdout`).

Public: :data:`QUASI_STATIC_TOL`, :class:`FreeData`, :func:`hand_steps`, :func:`free_points`,
:func:`calibrate_free`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from workbench.analysis import mag_ellipsoid, mag_motion, mag_quality, mag_spikes, stationarity
from workbench.analysis.mag_attitude import down_direction
from workbench.analysis.mag_fit import MagFit
from workbench.analysis.mag_holdout import Fitter, halves, held_out, holdout_quality, jackknife_sigmas
from workbench.analysis.mag_quality import gravity_spread
from workbench.analysis.mag_select import Choice
from workbench.analysis.magnetometer import MIN_POINTS, MagCalibration, MagPoints, calibrate, fit_method
from workbench.errors import AnalysisError
from workbench.session import Session

QUASI_STATIC_TOL = 0.03  # relative deviation of the block's |f| from local gravity (3 %: ~1.7° worst-case tilt error)
BLOCK_S = 0.05  # s, length of one fit point's block
MIN_STILL_STRETCHES = 6  # still stretches (orientations) for a fit on still blocks alone
MIN_STILL_TILT = float(np.radians(30.0))  # rad, spread of their gravity directions
MIN_TRACKED = 30  # blocks with gravity tracked through the motion for them to carry the dip constraint


@dataclass(frozen=True)
class FreeData:
    """Points of the ``free`` steps: ``mag`` (N, 3) µT, ``accel`` (N, 3) m/s^2 block means, ``t`` (N,) s,
    ``step`` (N,), ``quasi_static`` (N,) bool, ``still`` (N,) bool (every sample of the block still); ``gravity`` m/s^2 the local |f| used;
    ``still_stretches`` the number found, ``still_s`` their total length, ``spike_t`` s; ``down`` (N, 3) the
    block's mean down direction, tracked through the motion with the gyro where ``tracked`` (N,) bool, and
    the ``timing`` fit that made it possible."""

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
    down: np.ndarray | None = None  # (N, 3) unit down directions (tracked through the motion when ``timing``)
    tracked: np.ndarray | None = None  # (N,) bool: every sample of the block tracked (mag_motion.track_down)
    timing: mag_motion.Timing | None = None  # magnetometer time offset and gyro bias, None: not fitted ...
    timing_note: str = ""  # ... and why not

    @property
    def uses_still(self) -> bool:
        """Whether the still blocks alone carry the fit: at least :data:`MIN_STILL_STRETCHES` stretches whose
        gravity directions span more than :data:`MIN_STILL_TILT` (else the quasi-static blocks do)."""
        if self.still_stretches < MIN_STILL_STRETCHES or self.still.sum() < 15:
            return False
        return gravity_spread(down_direction(self.accel[self.still])) > MIN_STILL_TILT

    @property
    def uses_tracked(self) -> bool:
        """Whether the blocks with gravity tracked through the motion carry the dip constraint (the still ones do
        not suffice, and at least :data:`MIN_TRACKED` blocks are tracked)."""
        return not self.uses_still and self.tracked is not None and int(self.tracked.sum()) >= MIN_TRACKED

    def fit_mask(self) -> np.ndarray:
        """(N,) the blocks whose gravity direction is known: the still ones when they suffice (:attr:`uses_still`),
        else the tracked ones (:attr:`uses_tracked`), else the quasi-static ones."""
        if self.uses_still:
            return self.still
        return self.tracked if self.uses_tracked else self.quasi_static

    def down_directions(self) -> np.ndarray:
        """(N, 3) unit down direction of every block: tracked through the motion when a timing fit was made,
        else the accelerometer's."""
        return self.down if self.down is not None else down_direction(self.accel)

    def describe(self) -> str:
        """One phrase naming the data: steps, blocks fitted and why, still stretches."""
        names = ", ".join(str(s) for s in self.steps)
        head = (f"{'free step' if self.free else 'step'}{'s' if len(self.steps) > 1 else ''} {names} "
                f"(by hand, no table attitude), "
                f"{self.still_stretches} still stretch(es) ({self.still_s:.1f} s): ")
        head += f"all {len(self.t)} {BLOCK_S * 1e3:g}-ms blocks carry the field norm, "
        timing = (self.timing.describe() if self.timing is not None else
                  f"no magnetometer timing fit ({self.timing_note})" if self.timing_note else "")
        if self.uses_still:
            return head + f"the {int(self.still.sum())} of the still stretches gravity" + (f"; {timing}" if timing else "")
        if self.uses_tracked:
            return head + (f"too few still orientations: the {int(self.tracked.sum())} with gravity tracked through "
                           f"the motion (gyro-aided, {mag_motion.TRACK_TC_S:g}-s smoother both ways, not within "
                           f"{mag_motion.SETTLE_TC * mag_motion.TRACK_TC_S:g} s of a gyro saturation) carry it; {timing}")
        return head + (f"too few still orientations: the {int(self.quasi_static.sum())} quasi-static ones "
                       f"(|f| within {QUASI_STATIC_TOL:.0%} of {self.gravity:.3f} m/s²) gravity"
                       + (f"; {timing}" if timing else ""))


def hand_steps(session: Session) -> list:
    """The steps whose attitude only the unit's own sensors know: kind ``free``, or a turn declared ``by_hand``
    (an imported hand-made turn: its table angle is a guess, never a measurement)."""
    return [st for st in session.steps if st.kind == "free" or bool(st.extra.get("by_hand"))]


def _timing(frames: list, mags: list, gyros: list, ok_g: list, ok_m: list) -> tuple[mag_motion.Timing | None, str]:
    """The magnetometer's time offset and the gyro bias from the field's rotation (:mod:`mag_motion`), or
    (None, why not): only on a 3D cloud (a level turn's rough ellipsoid has no direction to give)."""
    good = np.concatenate([m[ok] for m, ok in zip(mags, ok_m)])
    if len(good) < 10:
        return None, "too few magnetometer samples"
    sv = np.linalg.svd(good - good.mean(axis=0), compute_uv=False) / np.sqrt(len(good))
    if sv[2] < MIN_CLOUD_UT:
        return None, f"the field did not turn out of a plane ({sv[2]:.3g} µT < {MIN_CLOUD_UT:g} µT)"
    try:
        rough = mag_ellipsoid.fit_algebraic_plain(good)
        segments = [(df["t"].to_numpy(float), m, g, om & og) for (_, df), m, g, om, og in
                    zip(frames, mags, gyros, ok_m, ok_g)]
        return mag_motion.fit_timing(segments, rough.compensate), ""
    except AnalysisError as exc:
        return None, str(exc)


def free_points(session: Session, block_s: float = BLOCK_S, reject_spikes: bool = True,
                accel_model=None) -> FreeData:
    """Block means of the magnetometer and accelerometer on the session's ``free`` steps, and the down
    direction tracked through the motion.

    Samples the import flagged (repeated or saturated) are left out of the means; with
    ``reject_spikes``, magnetometer spikes in the still stretches too (:mod:`mag_spikes`). ``accel_model``
    compensates the accelerometer first. On a 3D cloud the magnetometer's time offset to the gyro and the
    gyro bias are fitted (:func:`workbench.analysis.mag_motion.fit_timing`), the offset corrected when
    significant, and gravity tracked with the gyro (:func:`workbench.analysis.mag_motion.track_down`).
    Raises AnalysisError when there is no free step or no block with samples.
    """
    steps = hand_steps(session)
    if not steps:
        raise AnalysisError(f"{session.name}: no free step (nor a step turned by hand)")
    if not session.has_mag:
        raise AnalysisError(f"{session.name}: samples have no magnetometer columns mx, my, mz")
    frames = [(st, session.step_samples(st.index)) for st in steps]
    frames = [(st, df) for st, df in frames if len(df)]
    raw = [df[["mx", "my", "mz"]].to_numpy(float) for _, df in frames]
    gyros = [df[["gx", "gy", "gz"]].to_numpy(float) for _, df in frames]
    good_m = [session.good("mag", st.index) for st, _ in frames]
    good_g = [session.good("gyro", st.index) for st, _ in frames]
    timing, timing_note = _timing(frames, raw, gyros, good_g, good_m)
    mags, accs, downs, ts, labels, norms_still, spike_t, blk_still, blk_tracked = [], [], [], [], [], [], [], [], []
    n_still, still_s = 0, 0.0
    for (st, df), m, g, ok_m, ok_g in zip(frames, raw, gyros, good_m, good_g):
        t = df["t"].to_numpy(float)
        spike = np.zeros(len(df), bool)
        a = df[["ax", "ay", "az"]].to_numpy(float)
        if accel_model is not None:
            a = accel_model.compensate(a)
        ok_a = session.good("accel", st.index)
        if timing is not None and timing.significant and ok_m.sum() > 1:
            m, ok_m = mag_motion.shift(t, m, ok_m, timing.delay_s)
        still = np.zeros(len(df), bool)
        if len(df) >= max(3, int(0.5 * session.sample_rate_hz)):
            found = stationarity.detect(g, a, session.sample_rate_hz)
            still = found.still
            n_still += len(found.stretches)
            still_s += float(still.sum() / session.sample_rate_hz)
            if still.any():
                norms_still.append(np.linalg.norm(a[still & ok_a], axis=1))
        down, tracked = down_direction(a), np.zeros(len(t), bool)
        if timing is not None and len(t) > 1:
            # where the unit is still the accelerometer alone gives gravity; the tracker carries it through the motion
            moving, tracked = mag_motion.track_down(t, a, timing.rate(g), ~ok_g)
            down = np.where(still[:, None], down, moving)
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
            d = down[sel].mean(axis=0)
            downs.append(d / np.linalg.norm(d))
            ts.append(float(t[sel].mean()))
            labels.append(st.index)
            blk_still.append(bool(still[sel].all()))
            blk_tracked.append(bool(tracked[sel].all()))
    if not mags:
        raise AnalysisError(f"{session.name}: free steps have no samples usable for a magnetometer fit")
    acc = np.array(accs)
    norm = np.linalg.norm(acc, axis=1)
    still_norms = np.concatenate(norms_still) if norms_still else np.zeros(0)
    grav = float(np.median(still_norms)) if len(still_norms) else float(np.median(norm))
    quasi = np.abs(norm / grav - 1.0) < QUASI_STATIC_TOL
    return FreeData(np.array(mags), acc, np.array(ts), np.array(labels), quasi, np.array(blk_still), grav, n_still,
                    still_s, tuple(st.index for st, _ in frames),
                    np.concatenate(spike_t) if spike_t else np.zeros(0),
                    all(st.kind == "free" for st, _ in frames), np.array(downs), np.array(blk_tracked), timing,
                    timing_note)


def _choose(fitters: dict[str, Fitter], mag: np.ndarray, down: np.ndarray, gravity_ok: np.ndarray,
            t: np.ndarray) -> Choice:
    """The estimator whose field-to-gravity angle spread, held out both ways (fit on one half in time, judge
    on the other), is the smaller; the constant-dip fit on a tie. The reason gives the figures."""
    _, first, second = halves(t)
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

    Every block carries the field-norm constraint; the blocks whose gravity direction is known (the still
    ones when they suffice, else the tracked ones, else the quasi-static ones: :meth:`FreeData.fit_mask`)
    also carry the dip constraint and judge the angle.
    ``auto`` chooses between the constant-dip fit and the ellipsoid by their held-out angle spread
    (:func:`_choose`); the reason names the data and the figures. The result carries the
    :class:`FreeQuality` figures. ``accel_model`` compensates the accelerometer first.
    """
    data = free_points(session, reject_spikes=robust is not False, accel_model=accel_model)
    q = data.fit_mask()
    if q.sum() < MIN_POINTS["dip"]:
        raise AnalysisError(f"{session.name}: {data.describe()}: too few points with gravity for a fit "
                            f"(need {MIN_POINTS['dip']}); hold the unit still or turn it more slowly")
    down = data.down_directions()
    accel = -data.gravity * down  # the specific force of gravity alone, along the (tracked) down direction
    points = MagPoints(data.mag, accel, None, None, data.step, None, data.t, data.spike_t, q)

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
                    reference=reference, source=session.name, data=data.describe(), choice=choice,
                    accel_compensated=True)
    quality = holdout_quality(fitter(cal.fit.method), cal.fit, data.mag, accel, data.t, q)
    fit = jackknife_sigmas(fitter(cal.fit.method), cal.fit, len(data.t))
    return replace(cal, fit=fit, free_quality=quality,
                   motion=None if data.timing is None else data.timing.to_dict())
