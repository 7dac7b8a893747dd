"""Why a hand-held magnetometer fit does worse held out than in sample: the candidate causes, measured.

    python benchmarks/mag_holdout_causes.py SESSION_DIR        # e.g. runs/marg/tilt-sphere (README section)

The held-out figures of ``workbench analyze magnetometer`` on a ``free`` session fit on the points before the
median time and judge the points after it. This prints, on the same 50-ms points (``mag_free.free_points``):

1. the held-out field-norm residual of the ellipsoid split into what a constant norm change, a hard-iron
   change (linear in the field direction ``u``: a body-frame offset ``d`` adds ``u . A^-1 d`` to the norm)
   and a soft-iron change explain, beside the in-sample residual (the noise floor of any constant
   calibration);
2. a comparison that needs no fit on either half: block pairs, one from each half, whose calibrated field
   directions agree within 5°: their norm difference regressed on ``[1, u]`` (a constant calibration
   gives zero whatever the misfit, since both blocks see the same field direction);
3. the candidate causes: rate of turn (block averaging, interpolation, time alignment), die temperature,
   nearness to a gyro saturation, isolated single-sample jumps (a read mixing two samples' axes), a hard
   iron linear in time fitted on the first half and extrapolated, the magnetometer time offset in 8-s
   windows (each stream's clock is fitted to its own arrival stamps);
4. the held-out field-to-gravity angle spread of the ellipsoid and of the plain algebraic ellipsoid, with
   the moving-block bootstrap (2-s blocks of the second half) standard error of their difference.

Nothing here is fitted on the second half and then judged on it, except where a line says "in sample".
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.optimize import least_squares

from workbench.analysis import mag_ellipsoid, mag_free, mag_motion
from workbench.analysis.mag_holdout import halves, point_values
from workbench.session import load_session

MATCH_DEG = 5.0  # blocks of the two halves "see the same field direction" within this angle
WINDOW_S = 8.0  # s, windows of the magnetometer time-offset fit (half-overlapping)
BOOT_BLOCK_S = 2.0  # s, blocks of the moving-block bootstrap
BOOT_N = 400


def _lsq(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float]:
    c = np.linalg.lstsq(x, y, rcond=None)[0]
    return c, float(np.sqrt(np.mean((y - x @ c) ** 2)))


def norm_decomposition(fit1, fit_all, mag, t, second) -> None:
    """Item 1: the second half's norm residual (µT) of the first half's fit, and what each term explains."""
    h = fit1.compensate(mag[second])
    n = np.linalg.norm(h, axis=1)
    e, u = n - fit1.field_norm_ut, h / n[:, None]
    ones = np.ones((len(e), 1))
    quad = np.column_stack([u[:, 0] ** 2 - u[:, 2] ** 2, u[:, 1] ** 2 - u[:, 2] ** 2, u[:, 0] * u[:, 1],
                            u[:, 0] * u[:, 2], u[:, 1] * u[:, 2]])
    in_sample = np.linalg.norm(fit_all.compensate(mag), axis=1) - fit_all.field_norm_ut
    print(f"1. held-out norm residual of the ellipsoid fitted on the first half: rms {np.sqrt(np.mean(e ** 2)):.3f} µT "
          f"({100 * np.sqrt(np.mean(e ** 2)) / fit1.field_norm_ut:.2f} %); in sample (all points) "
          f"{np.sqrt(np.mean(in_sample ** 2)):.3f} µT")
    for label, x in (("a constant norm change", ones), ("+ a hard-iron change (linear in u)", np.hstack([ones, u])),
                     ("+ a soft-iron change (quadratic in u)", np.hstack([ones, u, quad]))):
        c, left = _lsq(x, e)
        extra = f": constant {c[0]:+.2f} µT, hard-iron term ({', '.join(f'{v:+.2f}' for v in c[1:4])}) µT" \
            if x.shape[1] == 4 else ""
        print(f"   left after {label}: rms {left:.3f} µT{extra}")


def matched_directions(fit_all, mag, t, q, first, second) -> None:
    """Item 2: norm differences of block pairs (late - early) that see the same calibrated field direction."""
    h = fit_all.compensate(mag)
    n = np.linalg.norm(h, axis=1)
    u = h / n[:, None]
    a, b = np.flatnonzero(first), np.flatnonzero(second)
    ib, ia = np.nonzero(u[b] @ u[a].T > np.cos(np.radians(MATCH_DEG)))
    dn = n[b][ib] - n[a][ia]
    c, left = _lsq(np.column_stack([np.ones(len(ib)), u[b][ib]]), dn)
    print(f"2. {len(ib)} block pairs (late - early, {len(np.unique(ib))} late and {len(np.unique(ia))} early blocks) "
          f"with the same field direction within {MATCH_DEG:g}°: norm difference rms {np.sqrt(np.mean(dn ** 2)):.3f} µT "
          f"= {c[0]:+.2f} µT + u . ({', '.join(f'{v:+.2f}' for v in c[1:])}) µT, {left:.3f} µT left")


def causes(session, data, fit_all, fit1) -> None:
    """Item 3: the candidate causes of the norm residual, and the time-linear hard iron extrapolated."""
    df = session.step_samples(data.steps[0])
    ts = df["t"].to_numpy(float)
    block = np.floor((ts - ts[0]) / mag_free.BLOCK_S).astype(int)
    k = np.floor((data.t - ts[0]) / mag_free.BLOCK_S).astype(int)
    rate = np.linalg.norm(df[["gx", "gy", "gz"]].to_numpy(float), axis=1)
    rate_b = np.bincount(block, rate) / np.maximum(np.bincount(block), 1)
    e = 100 * point_values(fit_all, data.mag, data.down_directions())[0]
    w = rate_b[k]
    print("3. in-sample norm residual (%) against the candidate causes:")
    bins = [(0, 0.5), (0.5, 1), (1, 2), (2, 3), (3, 5)]
    print("   rate of turn (rad/s): " + ", ".join(f"{lo:g}-{hi:g}: mean {e[(w >= lo) & (w < hi)].mean():+.2f} "
                                               f"rms {np.sqrt(np.mean(e[(w >= lo) & (w < hi)] ** 2)):.2f} "
                                               f"(n {int(((w >= lo) & (w < hi)).sum())})"
                                               for lo, hi in bins if ((w >= lo) & (w < hi)).any())
          + f"; correlation {np.corrcoef(e, w)[0, 1]:+.2f}")
    if "temp" in df:
        temp = df["temp"].to_numpy(float)
        tb = (np.bincount(block, temp) / np.maximum(np.bincount(block), 1))[k]
        print(f"   die temperature {temp.min():.2f}-{temp.max():.2f} °C, correlation {np.corrcoef(e, tb)[0, 1]:+.2f}")
    sat = ts[~session.good("gyro", data.steps[0])]
    near = np.array([np.any(np.abs(sat - x) < 0.5) for x in data.t]) if len(sat) else np.zeros(len(e), bool)
    if near.any():
        print(f"   within 0.5 s of a gyro saturation: rms {np.sqrt(np.mean(e[near] ** 2)):.2f} % ({int(near.sum())} blocks), "
              f"elsewhere {np.sqrt(np.mean(e[~near] ** 2)):.2f} %")
    m = df[["mx", "my", "mz"]].to_numpy(float)[session.good("mag", data.steps[0])]
    r = np.linalg.norm(fit_all.compensate(m), axis=1) - fit_all.field_norm_ut
    jump = r[1:-1] - 0.5 * (r[:-2] + r[2:])
    big = np.abs(jump) > 8 * 1.4826 * np.median(np.abs(jump))
    print(f"   isolated single-sample norm jumps over 8 robust sigma: {int(big.sum())} of {len(jump)} magnetometer samples (on the IMU instants)")
    # a hard iron linear in time, fitted on the first half (soft iron with it) and extrapolated
    split, first, second = halves(data.t)
    lin = np.linalg.inv(fit1.field_norm_ut * fit1.soft_iron)
    iu = np.triu_indices(3)

    def resid(p, sel):
        lm = np.zeros((3, 3))
        lm[iu] = p[:6]
        lm = lm + np.triu(lm, 1).T
        b = p[6:9] + np.outer(data.t[sel] - split, p[9:12])
        return np.linalg.norm((data.mag[sel] - b) @ lm.T, axis=1) - 1.0

    p = least_squares(resid, np.concatenate([lin[iu], fit1.bias, np.zeros(3)]), args=(first,)).x
    print(f"   hard iron linear in time, fitted on the first half, extrapolated: held-out norm RMS "
          f"{100 * np.sqrt(np.mean(resid(p, second) ** 2)):.2f} % (drift ({', '.join(f'{v:+.3f}' for v in p[9:12])}) µT/s)")
    t, g = ts, df[["gx", "gy", "gz"]].to_numpy(float)
    ok = session.good("mag", data.steps[0]) & session.good("gyro", data.steps[0])
    rough = mag_ellipsoid.fit_algebraic_plain(df[["mx", "my", "mz"]].to_numpy(float)[ok])
    taus = []
    for t0 in np.arange(t[0], t[-1] - WINDOW_S / 2, WINDOW_S / 2):
        sel = (t >= t0) & (t < t0 + WINDOW_S)
        try:
            f = mag_motion.fit_timing([(t[sel], df[["mx", "my", "mz"]].to_numpy(float)[sel], g[sel], ok[sel])],
                                      rough.compensate)
        except Exception:  # noqa: BLE001 - a window the field did not turn enough in
            continue
        taus.append((f.delay_s, f.delay_sigma))
    if taus:
        d, s = np.array(taus).T
        chi2 = float(np.sum(((d - np.average(d, weights=s ** -2)) / s) ** 2))
        print(f"   magnetometer time offset in {WINDOW_S:g}-s windows: {1e3 * d.min():+.1f} to {1e3 * d.max():+.1f} ms "
              f"(sigmas {1e3 * s.min():.1f}-{1e3 * s.max():.1f} ms, chi2 {chi2:.0f} on {len(d) - 1} dof; "
              "a time error turns the field, it leaves its norm)")


def angle_difference(fit_fn, base_fn, mag, down, q, t, first, second) -> None:
    """Item 4: held-out angle spread of the two fits and the bootstrap standard error of their difference."""
    a1, b1 = fit_fn(mag[first]), base_fn(mag[first])
    sel = second & q
    ang_a = point_values(a1, mag[sel], down[sel])[1]
    ang_b = point_values(b1, mag[sel], down[sel])[1]
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
    args = ap.parse_args(argv)
    session = load_session(args.session)
    data = mag_free.free_points(session)
    mag, t, q, down = data.mag, data.t, data.fit_mask(), data.down_directions()
    _, first, second = halves(t)
    fit_all, fit1 = mag_ellipsoid.fit_ellipsoid(mag), mag_ellipsoid.fit_ellipsoid(mag[first])
    print(f"{session.name}: {len(t)} points, {int(q.sum())} with gravity; held out = fitted on t <= {np.median(t):.1f} s")
    norm_decomposition(fit1, fit_all, mag, t, second)
    matched_directions(fit_all, mag, t, q, first, second)
    causes(session, data, fit_all, fit1)
    angle_difference(mag_ellipsoid.fit_ellipsoid, mag_ellipsoid.fit_algebraic_plain, mag, down, q, t, first, second)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
