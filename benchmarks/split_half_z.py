"""Split-half z-scores of every coefficient on a recorded session: are the sigmas honest on real data?

The session is cut in two halves in time: every step whose data can be cut (static holds,
free motion) keeps its first half in A and its second half in B; a step that must stay whole
(a turn, an index move) goes whole into both (its coefficients are then not independent between
A and B and are left out: ``--shared``). Both halves are analysed by the same procedure and
each coefficient that both observe gives ``z = (x_A - x_B) / sqrt(s_A² + s_B²)``. With honest
sigmas z is N(0, 1): rms z ~ 1 (target <= 1.5 on real recordings, issue 21 item 6).

    python benchmarks/split_half_z.py SESSION_DIR --procedure ferraris
    python benchmarks/split_half_z.py runs/imucal --procedure ferraris -o position_sigma_deg=auto
    python benchmarks/split_half_z.py runs/unmoved-* --procedure multiposition --across
    python benchmarks/split_half_z.py runs/tilt-sphere --procedure magnetometer --sim 100
    python benchmarks/split_half_z.py runs/tilt-sphere --procedure magnetometer --handheld 12 --still 3

``--across``: a check that no scaling from a split can make circular: every recording fitted
whole, z between recordings of the same board for each coefficient both observe.

A sigma part that both halves share by construction (the gyro bias's unobserved g-sensitivity
``sigma_G |f|``: both halves hold the same orientation, so ``G f`` cancels in their difference) is
taken out of the split-half z (``COMMON``: the note holding it), and kept in ``--across`` (two
recordings in different orientations do see it).

Prints one row per coefficient (value in lab units, both halves, z) and the rms per triad and
over all.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

CUTTABLE = ("static", "free", "soak")
# coefficients fitted from steps that stay whole in both halves (turns): not independent
SHARED = {"ferraris": ("gyro.scale_misalignment", "gyro.nonlinearity"),
          "multiposition": (), "magnetometer": ()}
# (triad, field) -> the set note (procedure, triad, key) holding the part of its sigma common to both halves, SI
COMMON = {("gyro", "bias"): "bias_sigma_g_sensitivity"}


def halves(session):
    """Two sessions: the first and the second half in time of every cuttable step (others whole in both)."""
    df = session.samples
    keep_a = np.zeros(len(df), bool)
    keep_b = np.zeros(len(df), bool)
    steps_a, steps_b = [], []
    t = df["t"].to_numpy(float)
    lab = df["step"].to_numpy()
    for st in session.steps:
        rows = lab == st.index
        if st.kind not in CUTTABLE:
            keep_a |= rows
            keep_b |= rows
            steps_a.append(st)
            steps_b.append(st)
            continue
        tt = t[rows]
        if len(tt) < 4:
            continue
        mid = 0.5 * (tt[0] + tt[-1])
        keep_a |= rows & (t < mid)
        keep_b |= rows & (t >= mid)
        steps_a.append(replace(st, t_end=float(mid)))
        steps_b.append(replace(st, t_start=float(mid)))
    a = replace(session, steps=steps_a, samples=df[keep_a].reset_index(drop=True), id=session.id + "-A")
    b = replace(session, steps=steps_b, samples=df[keep_b].reset_index(drop=True), id=session.id + "-B")
    return a, b


def _common_sigma(cal, triad: str, field: str) -> np.ndarray | None:
    """The part of ``triad.field``'s sigma a set's notes say both halves of a record share (:data:`COMMON`), SI."""
    key = COMMON.get((triad, field))
    for notes in cal.notes.values():
        value = notes.get(triad, {}).get(key) if key and isinstance(notes, dict) else None
        if isinstance(value, list):
            return np.asarray(value, float)
    return None


def coefficients(cal, within: bool = False):
    """(triad, field, index, value SI, sigma SI) of every observed coefficient of a set; ``within``: the sigma
    without the part common to both halves of one record (:data:`COMMON`)."""
    out = []
    for triad, tc in cal.triads.items():
        m = tc.model
        fields = {"bias": m.bias, "scale_misalignment": m.scale_misalignment, "nonlinearity": m.nonlinearity,
                  "g_sensitivity": m.g_sensitivity}
        for name, arr in fields.items():
            if arr is None:
                continue
            sig = tc.sigma_of(name)
            common = _common_sigma(cal, triad, name) if within else None
            if common is not None:
                sig = np.sqrt(np.clip(np.square(sig) - np.square(common), 0.0, None))
            for idx in np.ndindex(np.shape(arr)):
                if np.isfinite(sig[idx]) and sig[idx] > 0:
                    out.append((triad, name, idx, float(arr[idx]), float(sig[idx])))
        if tc.field_norm_ut is not None and tc.field_norm_ut_sigma is not None and np.isfinite(tc.field_norm_ut_sigma):
            out.append((triad, "field_norm", (), float(tc.field_norm_ut), float(tc.field_norm_ut_sigma)))
    return out


def split_half_z(session, proc, options: dict, shared=()) -> list[tuple]:
    """Rows (name, unit, value_A, value_B, sigma_A, sigma_B, z) of the coefficients both halves observe."""
    from workbench import units

    a, b = halves(session)
    ca = {(t, f, i): (v, s) for t, f, i, v, s in coefficients(proc.analyze(a, **options).calibration, True)}
    cb = {(t, f, i): (v, s) for t, f, i, v, s in coefficients(proc.analyze(b, **options).calibration, True)}
    rows = []
    for key in ca.keys() & cb.keys():
        triad, field, idx = key
        if f"{triad}.{field}" in shared:
            continue
        (va, sa), (vb, sb) = ca[key], cb[key]
        q = "field_norm" if field == "field_norm" else units.field_quantity(field, idx)
        unit = units.unit_of(triad, q)
        rows.append((f"{triad} {field}{list(idx) if idx else ''}", unit, va, vb, sa, sb,
                     (va - vb) / np.hypot(sa, sb)))
    return sorted(rows)


def across_z(sessions: list, proc, options: dict) -> list[tuple]:
    """Rows (name, unit, value_A, value_B, sigma_A, sigma_B, z, pair) between whole recordings of one unit.

    Independent of any scaling of the sigmas by a split: every recording is fitted whole, and a
    coefficient observed by two recordings gives ``z = (x_A - x_B) / sqrt(s_A² + s_B²)`` (same
    board, different recordings: a change of the unit between them also shows, as it should).
    """
    from itertools import combinations

    from workbench import units
    from workbench.errors import WorkbenchError

    fits = {}
    for s in sessions:
        try:
            fits[s.name] = {(t, f, i): (v, sg) for t, f, i, v, sg in coefficients(proc.analyze(s, **options).calibration)}
        except WorkbenchError as exc:
            print(f"{s.name}: not fitted ({str(exc)[:100]})")
    rows = []
    for (na, ca), (nb, cb) in combinations(fits.items(), 2):
        for key in sorted(ca.keys() & cb.keys()):
            triad, field, idx = key
            (va, sa), (vb, sb) = ca[key], cb[key]
            q = "field_norm" if field == "field_norm" else units.field_quantity(field, idx)
            rows.append((f"{triad} {field}{list(idx) if idx else ''}", units.unit_of(triad, q), va, vb, sa, sb,
                         (va - vb) / np.hypot(sa, sb), f"{Path(na).name} vs {Path(nb).name}"))
    return rows


def sim_coverage(seeds: int = 100) -> None:
    """Coverage of the 1-sigma intervals against the virtual lab's truth (noise correlated in time).

    The two experiments of ``tests/analysis/test_mag_fit_sigma.py`` (hand-held tumble, Gauss-Markov
    noise over ~40 points: hard iron) and ``tests/analysis/test_position_check_noise.py`` (six
    10-s positions of an industrial MEMS unit, Gauss-Markov drift on the accelerometer: its bias),
    with the white-noise covariance beside the one the workbench reports.
    """
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from tests.analysis import test_mag_fit_sigma as mag
    from workbench.analysis import mag_fit

    def band(n: int) -> str:
        return f"binomial 3σ band {0.683 - 3 * np.sqrt(0.683 * 0.317 / n):.2f}-{0.683 + 3 * np.sqrt(0.683 * 0.317 / n):.2f}"

    def zs(cov_fn=None) -> dict[str, list[float]]:
        saved = mag_fit._covariance
        if cov_fn is not None:
            mag_fit._covariance = cov_fn
        out: dict[str, list[float]] = {"hard iron": [], "soft iron diagonal": [], "soft iron off-diagonal": []}
        try:
            for seed in range(seeds):
                fit = mag.fit_ellipsoid(mag._points(seed), field_norm_ut=48.0)
                out["hard iron"] += list((fit.bias - mag.HARD) / fit.bias_sigma)
                z = (fit.soft_iron - mag.SOFT) / fit.soft_iron_sigma
                out["soft iron diagonal"] += list(np.diag(z))
                out["soft iron off-diagonal"] += list(z[np.triu_indices(3, 1)])
        finally:
            mag_fit._covariance = saved
        return out

    honest, white = zs(), zs(lambda jac, r: mag_fit.lsq_covariance(jac, r.ravel()))
    print(f"sim: magnetometer tumble, Gauss-Markov noise over ~40 points, {seeds} seeds (truth known)")
    for key in honest:
        h = np.array([z for z in honest[key] if np.isfinite(z)])
        w = np.array([z for z in white[key] if np.isfinite(z)])
        print(f"  {key:24s} {len(h)} z: coverage {np.mean(np.abs(h) < 1):.2f}, rms z {np.sqrt(np.mean(h ** 2)):.2f} "
              f"(white-noise covariance: {np.mean(np.abs(w) < 1):.2f}, rms z {np.sqrt(np.mean(w ** 2)):.2f}; "
              f"{band(len(h))})")


def handheld_coverage(seeds: int = 12, still_s: float = 0.0) -> None:
    """Coverage of the hand-held magnetometer fit's 1-sigma intervals (``calibrate_free``) against the virtual
    lab's truth: consumer_9axis boards turned by hand for 60 s (``workbench/sim/handheld.py``; ``still_s``
    holds between tumbles, 0 = tumbled throughout), with the sigmas from the record's blocks in time
    (``mag_holdout.jackknife_sigmas``) and without them (the noise model alone)."""
    from workbench.analysis import mag_free
    from workbench.errors import AnalysisError
    from workbench.grades import draw_unit, load_spec
    from workbench.sim.handheld import handheld_session

    spec = load_spec("consumer_9axis")
    keep = mag_free.jackknife_sigmas
    print(f"sim: hand-held magnetometer, {seeds} boards of 60 s, holds {still_s:g} s (truth known)")
    for label, fn in (("block jackknife", keep), ("noise model only", lambda fitter, fit, n: fit)):
        mag_free.jackknife_sigmas = fn
        z: dict[str, list[float]] = {"hard iron": [], "soft iron": [], "field norm": []}
        try:
            for seed in range(seeds):
                session, truth = handheld_session(draw_unit(spec, seed), seed, duration_s=60.0, still_s=still_s,
                                                  temperature_c=spec.t_ref_c)
                try:
                    fit = mag_free.calibrate_free(session, robust="auto", accel_model=truth.unit.accel).fit
                except AnalysisError as exc:
                    print(f"  seed {seed}: not fitted ({str(exc)[:80]})")
                    continue
                m = truth.unit.mag
                b = m.apply(np.zeros((3, 3)), None, np.full(3, spec.t_ref_c))[0]
                a = (m.apply(np.eye(3), None, np.full(3, spec.t_ref_c)) - b).T
                k = np.cbrt(np.linalg.det(a))  # det(I + M) = 1 fixes the fit's scale
                z["hard iron"] += list((fit.bias - b) / fit.bias_sigma)
                z["soft iron"] += list(((fit.soft_iron - a / k) / fit.soft_iron_sigma).ravel())
                z["field norm"].append((fit.field_norm_ut - np.linalg.norm(truth.field_ned) * k) / fit.field_norm_sigma)
        finally:
            mag_free.jackknife_sigmas = keep
        for key, v in z.items():
            v = np.array([x for x in v if np.isfinite(x)])
            print(f"  {label:17s} {key:10s} {len(v):4d} z: coverage {np.mean(np.abs(v) < 1):.2f}, "
                  f"rms z {np.sqrt(np.mean(v ** 2)):.2f}")


def main(argv: list[str] | None = None) -> int:
    from workbench.registry import procedure
    from workbench.session import load_session

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("session", nargs="+", help="one session (split in halves), or several with --across")
    ap.add_argument("--procedure", required=True)
    ap.add_argument("--across", action="store_true", help="z between whole recordings of one unit instead")
    ap.add_argument("--sim", type=int, default=0, metavar="SEEDS",
                    help="also print the coverage against the virtual lab's truth over SEEDS tumbles")
    ap.add_argument("--handheld", type=int, default=0, metavar="SEEDS",
                    help="also print the hand-held magnetometer fit's coverage against the truth over SEEDS boards")
    ap.add_argument("--still", type=float, default=0.0, help="--handheld: still holds (s) between tumbles")
    ap.add_argument("-o", "--option", action="append", default=[], help="analysis option key=value (JSON value)")
    ap.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = ap.parse_args(argv)
    options = {}
    for item in args.option:
        k, v = item.split("=", 1)
        try:
            options[k] = json.loads(v)
        except json.JSONDecodeError:
            options[k] = v
    proc = procedure(args.procedure)
    if args.sim:
        sim_coverage(args.sim)
    if args.handheld:
        handheld_coverage(args.handheld, args.still)
    if args.across:
        from workbench import units

        rows = across_z([load_session(p) for p in args.session], proc, options)
        for name, unit, va, vb, sa, sb, z, pair in rows:
            f, lab = units.factor(unit), units.label(unit)
            print(f"{name:28s} {va / f:11.4g} ± {sa / f:<9.2g} {vb / f:11.4g} ± {sb / f:<9.2g} {z:+7.2f}  {lab}  {pair}")
        z = np.array([r[6] for r in rows])
        if len(z):
            print(f"across recordings: {len(z)} coefficient pairs, rms z {np.sqrt(np.mean(z ** 2)):.2f}, "
                  f"max |z| {np.abs(z).max():.2f}")
        return 0
    session = load_session(args.session[0])
    rows = split_half_z(session, proc, options, SHARED.get(proc.NAME, ()))
    if args.json:
        print(json.dumps([dict(zip(("name", "unit", "a", "b", "sigma_a", "sigma_b", "z"), r)) for r in rows]))
        return 0
    from workbench import units

    print(f"{'coefficient':28s} {'first half':>24s} {'second half':>24s} {'z':>7s}")
    for name, unit, va, vb, sa, sb, z in rows:
        f = units.factor(unit)
        lab = units.label(unit)
        print(f"{name:28s} {va / f:11.4g} ± {sa / f:<9.2g} {vb / f:11.4g} ± {sb / f:<9.2g} {z:+7.2f}  {lab}")
    z = np.array([r[-1] for r in rows])
    for triad in sorted({r[0].split()[0] for r in rows}):
        zt = np.array([r[-1] for r in rows if r[0].startswith(triad + " ")])
        print(f"{triad}: {len(zt)} coefficients, rms z {np.sqrt(np.mean(zt ** 2)):.2f}, max |z| {np.abs(zt).max():.2f}")
    shared = SHARED.get(proc.NAME, ())
    print(f"all: {len(z)} coefficients, rms z {np.sqrt(np.mean(z ** 2)):.2f}, max |z| {np.abs(z).max():.2f}"
          + (f" (left out, shared whole steps: {', '.join(shared)})" if shared else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
