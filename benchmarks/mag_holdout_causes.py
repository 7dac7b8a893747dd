"""Why a hand-held magnetometer fit does worse held out than in sample: each physical cause tested, with its share.

    python benchmarks/mag_holdout_causes.py SESSION_DIR [--others SESSION_DIR ...]
    # e.g. runs/marg/tilt-sphere --others runs/marg/<every other recording> (docs/magnetometer.md)

The held-out figures of ``workbench analyze magnetometer`` on a ``free`` session fit on the points before the
median time and judge the points after it. On the same 50-ms points (``mag_free.free_points``) this prints:

1. the held-out field-norm RMS of the ellipsoid (and of the plain algebraic one), and its floor: the second
   half's own in-sample RMS (what a constant calibration fitted there leaves); the *excess* is the held-out
   mean square above the floor;
2. what changed between the halves: the held-out residual regressed on a constant norm change, a hard-iron
   change (linear in the field direction ``u``) and a soft-iron change (quadratic in ``u``); block pairs of the
   two halves seeing the same field direction (no fit on either half); the hard iron in 8-s windows (soft iron
   of the whole record held) beside the die temperature;
3. each cause, modelled on the first half alone and judged on the second, with its share of the excess
   ``(held-out MS - modelled MS) / excess``:
   - temperature: a hard iron linear in the die temperature (smoothed over 5 s: the MPU6050's reads come in
     0.094 °C steps), its coefficient ± sigma; with ``--others``, that coefficient (fitted on the whole record)
     and the constant calibration on the unit's other recordings, at other temperatures;
   - time: a hard iron linear in time; a warm-up ``exp(-t / tau)`` for several ``tau`` (and what the first
     half alone says about ``tau``); with ``--others``, the settled hard iron on the other recordings;
   - timing: the magnetometer's time offset scanned about the fitted one (the field-to-gravity angle and the
     norm held out, both fits), the offset in 8-s windows;
   - dynamics: the held-out angle spread of both fits by rate of turn (hand accelerations in the gravity);
   - rotation: the ellipsoid's field turned by the field-to-gyro rotation of the motion fit (angle only);
   - flagged samples: what the import left out (repeats, saturation), exact repeats left in, the fit
     without the blocks within 0.5 s of a gyro saturation, and the held-out residual near and away from them;
   - nonlinearity: a per-axis cubic term on the calibrated field (HMC5883L datasheet: linearity 0.1 % of
     the 2-gauss full scale, ~0.2 µT; cross-axis 0.2 % FS/gauss: a linear term the ellipsoid holds);
4. the held-out angle spread of the ellipsoid against the plain algebraic one, with the moving-block
   bootstrap (2-s blocks of the second half) standard error of their difference.

Nothing is fitted on the second half and judged on it, except the floor and the regressions of item 2.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from unittest import mock

import numpy as np
from scipy.optimize import least_squares

from workbench.analysis import mag_ellipsoid, mag_free, mag_motion
from workbench.analysis.mag_drift import fit_moving, norm_errors, smoothed_temperature
from workbench.analysis.mag_holdout import halves, point_values
from workbench.errors import AnalysisError
from workbench.session import FLAG_REPEATED, FLAG_SATURATED, load_session

MATCH_DEG = 5.0  # blocks of the two halves "see the same field direction" within this angle
WINDOW_S = 8.0  # s, windows of the hard-iron track and of the magnetometer time-offset fit (half-overlapping)
SMOOTH_S = 5.0  # s, die-temperature smoothing (several 0.094-°C steps dithered by its noise)
TAUS_S = (5.0, 10.0, 20.0, 40.0)  # s, warm-up time constants tried
DELAYS_S = (-0.015, -0.01, -0.005, 0.0, 0.005, 0.01)  # s, offsets added to the fitted magnetometer delay
SAT_S = 0.5  # s, "near a gyro saturation"
BOOT_BLOCK_S = 2.0  # s, blocks of the moving-block bootstrap
BOOT_N = 400


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def _lsq(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float]:
    c = np.linalg.lstsq(x, y, rcond=None)[0]
    return c, _rms(y - x @ c)


def _const_err(fit, mag: np.ndarray) -> np.ndarray:
    """Relative norm error (N,) of a constant calibration on raw points (N, 3) µT."""
    return np.linalg.norm(fit.compensate(mag), axis=1) / fit.field_norm_ut - 1.0


class Excess:
    """The held-out mean square of the ellipsoid above the second half's floor, and each cause's share of it."""

    def __init__(self, held: float, floor: float):
        self.held, self.floor, self.rows = held, floor, []

    def add(self, cause: str, rms: float, note: str = "") -> None:
        share = (self.held**2 - rms**2) / (self.held**2 - self.floor**2)
        self.rows.append((cause, rms, share, note))
        print(f"   {cause}: held-out norm RMS {100 * rms:.2f} % (share of the excess {share:+.0%}){note and '; ' + note}")

    def table(self) -> None:
        print(f"summary: held-out norm RMS {100 * self.held:.2f} %, floor {100 * self.floor:.2f} %; each cause "
              "modelled on the first half:")
        for cause, rms, share, _ in self.rows:
            print(f"   {cause:66s} {100 * rms:5.2f} %  share {share:+5.0%}")


def changes(fit1, fit_all, mag, t, temp, first, second) -> None:
    """Item 2: what changed between the halves."""
    h = fit1.compensate(mag[second])
    n = np.linalg.norm(h, axis=1)
    e, u = n - fit1.field_norm_ut, h / n[:, None]
    ones = np.ones((len(e), 1))
    quad = np.column_stack([u[:, 0] ** 2 - u[:, 2] ** 2, u[:, 1] ** 2 - u[:, 2] ** 2, u[:, 0] * u[:, 1],
                            u[:, 0] * u[:, 2], u[:, 1] * u[:, 2]])
    print(f"2. the held-out norm residual, {_rms(e):.3f} µT, regressed in sample on the second half:")
    for label, x in (("a constant norm change", ones), ("+ a hard-iron change (linear in u)", np.hstack([ones, u])),
                     ("+ a soft-iron change (quadratic in u)", np.hstack([ones, u, quad]))):
        c, left = _lsq(x, e)
        extra = (f": constant {c[0]:+.2f} µT, hard-iron term ({', '.join(f'{v:+.2f}' for v in c[1:4])}) µT"
                 if x.shape[1] == 4 else "")
        print(f"   left after {label}: rms {left:.3f} µT{extra}")
    hc = fit_all.compensate(mag)
    nc = np.linalg.norm(hc, axis=1)
    uc = hc / nc[:, None]
    a, b = np.flatnonzero(first), np.flatnonzero(second)
    ib, ia = np.nonzero(uc[b] @ uc[a].T > np.cos(np.radians(MATCH_DEG)))
    dn = nc[b][ib] - nc[a][ia]
    c, left = _lsq(np.column_stack([np.ones(len(ib)), uc[b][ib]]), dn)
    print(f"   {len(ib)} block pairs (late - early) with the same field direction within {MATCH_DEG:g}° (no fit on "
          f"either half): norm difference rms {_rms(dn):.3f} µT = {c[0]:+.2f} µT + u . "
          f"({', '.join(f'{v:+.2f}' for v in c[1:])}) µT, {left:.3f} µT left")
    lin = np.linalg.inv(fit_all.soft_iron)
    rows = []
    for t0 in np.arange(t[0], t[-1] - WINDOW_S / 2, WINDOW_S / 2):
        sel = (t >= t0) & (t < t0 + WINDOW_S)
        p = least_squares(lambda p: np.linalg.norm((mag[sel] - p[:3]) @ lin.T, axis=1) - p[3],
                          np.append(fit_all.bias, fit_all.field_norm_ut)).x
        rows.append(f"{t0:4.0f}-{t0 + WINDOW_S:.0f} s: {temp[sel].mean():.3f} °C, "
                    f"({', '.join(f'{v:+.2f}' for v in p[:3] - fit_all.bias)}) µT, norm {p[3] - fit_all.field_norm_ut:+.2f} µT")
    print(f"   hard iron in {WINDOW_S:g}-s windows (soft iron of the whole record held), minus the whole record's, "
          "beside the smoothed die temperature:\n      " + "\n      ".join(rows))


def temperature(ex: Excess, data, fit1, fit_all, temp, first, second, others) -> None:
    """Item 3, temperature: a hard iron linear in the die temperature; the other recordings."""
    mag = data.mag
    ref = float(temp[first].mean())
    m = fit_moving(mag[first], temp[first] - ref, fit1)
    print(f"   die temperature {temp.min():.3f}-{temp.max():.3f} °C smoothed over {SMOOTH_S:g} s (first half "
          f"{np.ptp(temp[first]):.3f} °C span, correlation with time {np.corrcoef(temp, data.t)[0, 1]:+.2f})")
    ex.add("hard iron linear in the die temperature", _rms(norm_errors(m, mag[second], temp[second] - ref)),
           f"k ({', '.join(f'{v:+.3g}' for v in m.rate)}) ± ({', '.join(f'{v:.2g}' for v in m.rate_sigma)}) µT/°C")
    if not others:
        return
    whole = fit_moving(mag, temp - ref, fit_all)
    print(f"   the same model on the whole record (k ({', '.join(f'{v:+.1f}' for v in whole.rate)}) µT/°C) and the "
          "constant calibration, on the unit's other recordings (all their unflagged samples):")
    worse = 0
    for s in others:
        st = s.steps[0].index
        df = s.step_samples(st)
        ok = s.good("mag", st)
        raw = _good_mag(s)
        ts = df["t"].to_numpy(float)
        dt = smoothed_temperature(ts, df["temp"].to_numpy(float), SMOOTH_S)[ok] - ref
        c, k = _rms(_const_err(fit_all, raw)), _rms(norm_errors(whole, raw, dt))
        worse += k > c
        print(f"      {s.name:42s} {dt.mean():+.2f} °C: constant {100 * c:5.2f} %, with k {100 * k:6.2f} %")
    print(f"   the coefficient does worse than the constant calibration on {worse} of {len(others)} recordings")


def time_models(ex: Excess, data, fit1, fit_all, first, second, split, others) -> None:
    """Item 3, time: linear drift and warm-up transients; the settled hard iron on the other recordings."""
    mag, t = data.mag, data.t
    m = fit_moving(mag[first], t[first] - split, fit1)
    ex.add("hard iron linear in time", _rms(norm_errors(m, mag[second], t[second] - split)),
           f"({', '.join(f'{v:+.3f}' for v in m.rate)}) µT/s")
    for tau in TAUS_S:
        x = np.exp(-(t - t[0]) / tau)
        m = fit_moving(mag[first], x[first], fit1)
        ex.add(f"warm-up exp(-t / {tau:g} s)", _rms(norm_errors(m, mag[second], x[second])),
               f"first half in sample {100 * m.rms:.3f} %")
    if others:
        x = np.exp(-(t - t[0]) / TAUS_S[2])
        settled = fit_moving(mag, x, fit_all)
        raws = [_good_mag(s) for s in others]
        print(f"   the settled hard iron of the exp(-t / {TAUS_S[2]:g} s) warm-up (whole record) on the other recordings: "
              f"median norm RMS {100 * np.median([_rms(norm_errors(settled, r, np.zeros(len(r)))) for r in raws]):.2f} %, "
              f"the constant calibration {100 * np.median([_rms(_const_err(fit_all, r)) for r in raws]):.2f} %")


def _good_mag(session) -> np.ndarray:
    """The unflagged raw magnetometer samples (N, 3) µT of a session's first step."""
    st = session.steps[0].index
    return session.step_samples(st)[["mx", "my", "mz"]].to_numpy(float)[session.good("mag", st)]


def _free_points_delayed(session, extra_s: float):
    """``free_points`` with ``extra_s`` added to the fitted magnetometer delay."""
    orig = mag_motion.fit_timing

    def shifted(*args, **kwargs):
        timing = orig(*args, **kwargs)
        return replace(timing, delay_s=timing.delay_s + extra_s)

    with mock.patch.object(mag_motion, "fit_timing", shifted):
        return mag_free.free_points(session)


def timing(ex: Excess, session, data) -> None:
    """Item 3, timing: held-out angle and norm against a delay added to the fitted one; windowed offsets."""
    print(f"   magnetometer delay fitted from the field's rotation: {1e3 * data.timing.delay_s:+.1f} ms; "
          "held out with an offset added:")
    best = None
    for extra in DELAYS_S:
        d = data if extra == 0.0 else _free_points_delayed(session, extra)
        q, down = d.fit_mask(), d.down_directions()
        _, first, second = halves(d.t)
        sel = second & q
        out = []
        for fn in (mag_ellipsoid.fit_ellipsoid, mag_ellipsoid.fit_algebraic_plain):
            f1 = fn(d.mag[first])
            out.append((np.degrees(np.std(point_values(f1, d.mag[sel], down[sel])[1])),
                        _rms(point_values(f1, d.mag[second], down[second])[0])))
        print(f"      {1e3 * (data.timing.delay_s + extra):+6.1f} ms: angle spread ellipsoid {out[0][0]:.3f}°, "
              f"plain {out[1][0]:.3f}° (difference {out[0][0] - out[1][0]:+.3f}°); norm {100 * out[0][1]:.2f} %")
        if best is None or out[0][0] < best[1]:
            best = (extra, out[0][0], out[0][1])
    ex.add(f"magnetometer delay {1e3 * (data.timing.delay_s + best[0]):+.1f} ms (smallest angle spread)", best[2],
           f"angle spread {best[1]:.3f}°")
    df = session.step_samples(data.steps[0])
    t, g, m = df["t"].to_numpy(float), df[["gx", "gy", "gz"]].to_numpy(float), df[["mx", "my", "mz"]].to_numpy(float)
    ok = session.good("mag", data.steps[0]) & session.good("gyro", data.steps[0])
    rough = mag_ellipsoid.fit_algebraic_plain(m[ok])
    taus = []
    for t0 in np.arange(t[0], t[-1] - WINDOW_S / 2, WINDOW_S / 2):
        sel = (t >= t0) & (t < t0 + WINDOW_S)
        try:
            f = mag_motion.fit_timing([(t[sel], m[sel], g[sel], ok[sel])], rough.compensate)
        except AnalysisError:  # a window the field did not turn enough in
            continue
        taus.append((f.delay_s, f.delay_sigma))
    if taus:
        dl, s = np.array(taus).T
        chi2 = float(np.sum(((dl - np.average(dl, weights=s ** -2)) / s) ** 2))
        print(f"   delay in {WINDOW_S:g}-s windows: {1e3 * dl.min():+.1f} to {1e3 * dl.max():+.1f} ms (sigmas "
              f"{1e3 * s.min():.1f}-{1e3 * s.max():.1f} ms, chi2 {chi2:.0f} on {len(dl) - 1} dof): the two streams' "
              "clocks, each fitted to its own arrival stamps, wander against each other")


def dynamics(session, data, first, second) -> None:
    """Item 3, dynamics: held-out angle spread by rate of turn, both fits."""
    df = session.step_samples(data.steps[0])
    ts = df["t"].to_numpy(float)
    block = np.floor((ts - ts[0]) / mag_free.BLOCK_S).astype(int)
    k = np.floor((data.t - ts[0]) / mag_free.BLOCK_S).astype(int)
    rate = np.linalg.norm(df[["gx", "gy", "gz"]].to_numpy(float), axis=1)
    w = (np.bincount(block, rate) / np.maximum(np.bincount(block), 1))[k]
    q, down = data.fit_mask(), data.down_directions()
    fits = [fn(data.mag[first]) for fn in (mag_ellipsoid.fit_ellipsoid, mag_ellipsoid.fit_algebraic_plain)]
    parts = []
    for lo, hi in ((0, 1), (1, 2), (2, 3), (3, 99)):
        sel = second & q & (w >= lo) & (w < hi)
        if sel.sum() > 5:
            a, b = (np.degrees(np.std(point_values(f, data.mag[sel], down[sel])[1])) for f in fits)
            parts.append(f"{lo}-{hi if hi < 99 else ''} rad/s ({int(sel.sum())}): {a:.2f}° / {b:.2f}°")
    print("   held-out angle spread (ellipsoid / plain) of the blocks with gravity, by rate of turn: " + "; ".join(parts))


def rotation(data, first, second) -> None:
    """Item 3, the magnetometer-to-IMU rotation (angle only): the ellipsoid's calibrated field turned by the rotation
    the field's turns show against the gyro (``Timing.rotation``, whole record), held out both ways."""
    q, down = data.fit_mask(), data.down_directions()
    r = data.timing.rotation()

    def spread(train, test, rot):
        h = mag_ellipsoid.fit_ellipsoid(data.mag[train]).compensate(data.mag[test & q]) @ rot.T
        cos = np.sum(h * down[test & q], axis=1) / np.linalg.norm(h, axis=1)
        return np.degrees(np.std(np.arccos(np.clip(cos, -1.0, 1.0))))

    parts = [f"{name} {spread(first, second, rot):.3f}° / {spread(second, first, rot):.3f}°"
             for name, rot in (("none", np.eye(3)), ("R", r), ("R^T", r.T))]
    print(f"   ellipsoid's field turned by the field-to-gyro rotation ({np.degrees(np.arccos((np.trace(r) - 1) / 2)):.2f}°), "
          "held-out angle spread first -> second / second -> first: " + ", ".join(parts))


def flagged(ex: Excess, session, data, first, second) -> None:
    """Item 3, flagged samples: what the import left out, repeats left in, saturation's neighbourhood."""
    st = data.steps[0]
    df = session.step_samples(st)
    flags = df["flags"].to_numpy(int) if "flags" in df else np.zeros(len(df), int)
    counts = {f"{name} {triad}": int(np.count_nonzero(flags & bits[triad])) for name, bits in
              (("repeated", FLAG_REPEATED), ("saturated", FLAG_SATURATED)) for triad in ("mag", "gyro", "accel")}
    m = df[["mx", "my", "mz"]].to_numpy(float)[session.good("mag", st)]
    left = int(np.count_nonzero(np.all(np.diff(m, axis=0) == 0, axis=1)))
    shown = ", ".join(f"{k} {v}" for k, v in counts.items() if v) or "none"
    print(f"   import flags (left out of every fit): {shown}; exact repeats among the magnetometer samples kept: {left}")
    sat = df["t"].to_numpy(float)[~session.good("gyro", st)]
    if not len(sat):
        print("   no gyro saturation")
        return
    near = np.array([np.any(np.abs(sat - x) < SAT_S) for x in data.t])
    f1, f1x = mag_ellipsoid.fit_ellipsoid(data.mag[first]), mag_ellipsoid.fit_ellipsoid(data.mag[first & ~near])
    ex.add(f"blocks within {SAT_S:g} s of a gyro saturation left out of the fit ({int((first & near).sum())})",
           _rms(_const_err(f1x, data.mag[second])))
    if (second & near).any() and (second & ~near).any():
        print(f"   judged apart (the first half's fit): the second half's {int((second & near).sum())} blocks within "
              f"{SAT_S:g} s of a gyro saturation {100 * _rms(_const_err(f1, data.mag[second & near])):.2f} %, the other "
              f"{int((second & ~near).sum())} {100 * _rms(_const_err(f1, data.mag[second & ~near])):.2f} % (where the "
              "hand turned fastest, not a corrupted fit)")


def nonlinearity(ex: Excess, data, fit1, first, second) -> None:
    """Item 3, nonlinearity: a per-axis cubic term on the calibrated field, fitted on the first half."""
    lin = np.linalg.inv(fit1.field_norm_ut * fit1.soft_iron)
    iu = np.triu_indices(3)

    def resid(p, sel):
        lm = np.zeros((3, 3))
        lm[iu] = p[:6]
        h = (data.mag[sel] - p[6:9]) @ (lm + np.triu(lm, 1).T).T
        return np.linalg.norm(h + p[9:12] * h**3, axis=1) - 1.0

    p = least_squares(resid, np.concatenate([lin[iu], fit1.bias, np.zeros(3)]), args=(first,)).x
    ex.add("per-axis cubic nonlinearity", _rms(resid(p, second)),
           f"cubic terms ({', '.join(f'{100 * v:+.1f}' for v in p[9:12])}) % at full field")


def angle_difference(data, first, second) -> None:
    """Item 4: held-out angle spread of the two fits and the bootstrap standard error of their difference."""
    mag, q, down, t = data.mag, data.fit_mask(), data.down_directions(), data.t
    sel = second & q
    ang_a = point_values(mag_ellipsoid.fit_ellipsoid(mag[first]), mag[sel], down[sel])[1]
    ang_b = point_values(mag_ellipsoid.fit_algebraic_plain(mag[first]), mag[sel], down[sel])[1]
    diff = np.degrees(np.std(ang_a) - np.std(ang_b))
    blk = np.floor((t[sel] - t[sel][0]) / BOOT_BLOCK_S).astype(int)
    ids = np.unique(blk)
    rng = np.random.default_rng(0)
    boot = []
    for _ in range(BOOT_N):
        pick = np.concatenate([np.flatnonzero(blk == i) for i in rng.choice(ids, len(ids))])
        boot.append(np.degrees(np.std(ang_a[pick]) - np.std(ang_b[pick])))
    print(f"4. held-out field-to-gravity angle spread: ellipsoid {np.degrees(np.std(ang_a)):.3f}°, plain algebraic "
          f"{np.degrees(np.std(ang_b)):.3f}°: difference {diff:+.3f}° ± {np.std(boot):.3f}° (moving-block bootstrap, "
          f"{BOOT_BLOCK_S:g}-s blocks, {len(ids)} blocks)")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("session", help="a session whose steps are free (imported hand-held recording)")
    ap.add_argument("--others", nargs="*", default=[], help="other sessions of the same unit (temperature check)")
    args = ap.parse_args(argv)
    session = load_session(args.session)
    others = [load_session(p) for p in args.others]
    data = mag_free.free_points(session)
    mag, t, q = data.mag, data.t, data.fit_mask()
    split, first, second = halves(t)
    fit_all, fit1 = mag_ellipsoid.fit_ellipsoid(mag), mag_ellipsoid.fit_ellipsoid(mag[first])
    held = _rms(_const_err(fit1, mag[second]))
    floor = _rms(_const_err(mag_ellipsoid.fit_ellipsoid(mag[second]), mag[second]))
    plain = _rms(_const_err(mag_ellipsoid.fit_algebraic_plain(mag[first]), mag[second]))
    df = session.step_samples(data.steps[0])
    ts, raw_temp = df["t"].to_numpy(float), df["temp"].to_numpy(float)
    temp = np.interp(t, ts, smoothed_temperature(ts, raw_temp, SMOOTH_S))
    levels = np.unique(raw_temp)
    print(f"{session.name}: {len(t)} points, {int(q.sum())} with gravity; held out = fitted on t <= {split:.1f} s")
    print(f"1. held-out norm RMS: ellipsoid {100 * held:.2f} %, plain algebraic {100 * plain:.2f} %; in sample (whole "
          f"record) {100 * _rms(_const_err(fit_all, mag)):.2f} %; floor (second half in sample) {100 * floor:.2f} %")
    changes(fit1, fit_all, mag, t, temp, first, second)
    ex = Excess(held, floor)
    print(f"3. causes, each modelled on the first half and judged on the second (die temperature: {len(levels)} "
          f"levels, steps {np.min(np.diff(levels)) if len(levels) > 1 else 0:.3f} °C):")
    temperature(ex, data, fit1, fit_all, temp, first, second, others)
    time_models(ex, data, fit1, fit_all, first, second, split, others)
    timing(ex, session, data)
    dynamics(session, data, first, second)
    rotation(data, first, second)
    flagged(ex, session, data, first, second)
    nonlinearity(ex, data, fit1, first, second)
    angle_difference(data, first, second)
    ex.table()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
