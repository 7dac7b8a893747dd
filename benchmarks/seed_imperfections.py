"""Thesis tables 4.3, 4.4 and the sec. 1.3 residuals through a virtual lab as imperfect as real units.

Seed: ``shared/seeds/000_*`` (thesis). Every figure is printed beside the seed's, for the
model-exact virtual lab ("exact") and with the imperfections switched on ("imperfect": the
grade's ``imperfections`` block, all groups, plus the table errors below), over ``--reps``
repetitions (each a fresh unit; each sequence of a repetition a fresh power-on of that unit,
as the thesis turns the unit off for an hour between sequences). Cells: median [min-max]
over the repetitions. The seed's figures are computed from its tables here (their rounding:
0.01° of a mean = 0.17 mrad) beside the figures its text states.

The site is the thesis's (40.8°) with the table's zero at azimuth 102.07° (the mean of table
4.3's sequences 1-4), so the sequences at home weight the x gyro and those at 90° the y gyro,
as in the thesis.

1. Table 4.3 (maytagging, sequences 1-4 at the home position, 5-7 at 90°; 40 ABAB pairs x 60 s
   from power-on, no warm-up discarded): per sequence, the std of its azimuths taken as the
   thesis takes them, one every 60 s from overlapping pairs (option ``pairs=sliding``: 79 from
   80 dwells; the thesis says 80), with the disjoint pairs' std beside; the per-pair theory (the
   grade's ADEV at the 58 s average, eq. of ``northfinding_theory.pair_azimuth_sigma``, and the
   analysis's own, with the dead time of the turn between a pair's two averages); the
   repeatability, the largest distance of a sequence mean from its group's mean (thesis
   2.4 / 0.75 mrad; table 4.3's means give 2.49 / 0.76); and the distance of the two group
   means (5-7 minus 1-4, the 90° removed: table 4.3 gives 90.68° - 90° = 11.9 mrad). Grades
   ``cvg_two_axis`` (table 4.1 read as the IEEE 952 B) and ``cvg_two_axis_adev_floor`` (read as
   the ADEV floor).
2. Table 4.4 (redundant configuration, sequences 8-12: 10 turns of 45° steps; 8-11 after one
   hour of warm-up, 12 at once): per pairing, the largest distance of a session's pairing mean
   from the mean over the five sessions (thesis 3.34-12.49 mrad), beside what the noise model alone
   gives (each session mean's sigma propagated with the bias wander, ``northfinding_spread``); how
   often session 12 is the farthest; and sequence 12's warm-up shift per pairing (its pairing mean minus that of 8-11,
   imperfect minus exact lab on the same seeds: the noise cancels, the warm-up stays), with its
   correlation to the thesis's eight figures.
3. Sec. 1.3 residuals (``industrial_mems``, the AX1-GNS3 class): a calibration session
   (24 positions x 60 s, then the rate procedure) and a second power-on compensated with its
   coefficients: the largest accelerometer residual (mg; thesis < 17 mg) and gyro residual
   (% of full scale; thesis < 0.7 %), beside the calibration session's own residuals.

Table errors of the imperfect lab (chosen: a mid-range positioning table, not the thesis's,
which gives none): indexing error 0.01°, wobble 0.003°, axis tilt 0.02°.
Samples are simulated at ``--rate-hz`` (default 20 Hz) to keep the run short: every figure
here is a mean over >= 58 s, which depends on the noise densities, not on the sample rate.

``--warm-up-scale K`` adds a what-if: the ADEV-floor grade's imperfect lab with its warm-up transient
times K (the fixture's 1 °/h over 15 min is chosen; the thesis gives no figure).

Usage: ``python benchmarks/seed_imperfections.py [--reps 10] [--rate-hz 20] [--only 4.3,4.4,1.3]
[--warm-up-scale 5] [--out FILE]``.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import procedures.maytagging as maytagging
import procedures.multiposition as multiposition
import procedures.rate as rate
import procedures.redundant as redundant
from workbench.analysis import northfinding as nfm
from workbench.analysis.northfinding_fit import maytag_azimuth
from workbench.analysis.northfinding_theory import adev_model, pair_azimuth_sigma
from workbench.analysis.turntable import fit_accel, fit_gyro_rate, fit_gyro_static
from workbench.angles import circular_mean
from workbench.grades import draw_unit, load_spec
from workbench.jobs import simulate
from workbench.model import TriadModel
from workbench.session import Site
from workbench.sim.imperfections import Imperfections

TABLE = {"table_indexing_error": np.radians(0.01), "table_wobble": np.radians(0.003),
         "table_axis_tilt": np.radians(0.02)}
MG = 9.80665e-3
# thesis table 4.3: mean azimuth [deg] and std [mrad] of sequences 1-7 (5-7 started 90° from home)
THESIS_43 = ((102.03, 8.60), (101.96, 9.47), (102.07, 6.75), (102.21, 9.33), (-167.21, 5.83), (-167.26, 8.80),
             (-167.29, 5.90))
THESIS_43_STATED = {"1-4": 2.4, "5-7": 0.75}  # repeatability [mrad], sec. 4.4.2
GROUPS = {"1-4": range(0, 4), "5-7": range(4, 7)}
OFFSETS_DEG = (0, 0, 0, 0, 90, 90, 90)
THESIS_44 = {"0-45": 6.63, "45-90": 12.49, "90-135": 6.18, "135-180": 3.34, "180-225": 3.46, "225-270": 8.46,
             "270-315": 9.56, "315-0": 4.17}
HOME_AZIMUTH_DEG = float(np.mean([m for m, _ in THESIS_43[:4]]))  # 102.07°: table zero of the simulated site
SITE = Site(40.8, 14.25, 30.0, table_zero_azimuth_deg=HOME_AZIMUTH_DEG)
DWELL_AVG_S = 58.0  # s averaged per dwell: 60 s minus the 2 s settling
GRADES = ("cvg_two_axis", "cvg_two_axis_adev_floor")


def lab(spec, imperfect: bool, warm_up_scale: float = 1.0) -> Imperfections | None:
    """The imperfections of the imperfect lab for ``spec`` (None: the model-exact lab), the grade's
    warm-up transient times ``warm_up_scale`` (a what-if: the thesis gives no warm-up figure)."""
    if not imperfect:
        return None
    imp = Imperfections.from_spec(spec, "all", **TABLE)
    return replace(imp, warm_up_bias={k: warm_up_scale * np.asarray(v) for k, v in imp.warm_up_bias.items()})


def cell(values) -> str:
    """median [min-max] of the repetitions."""
    v = np.asarray(values, float)
    return f"{np.median(v):.2f} [{v.min():.2f}-{v.max():.2f}]"


def thesis_43() -> dict:
    """Table 4.3's own figures (mrad): per group the stds, the repeatability, and the group-mean distance."""
    means = np.radians([m for m, _ in THESIS_43])
    out = {g: {"std": [THESIS_43[i][1] for i in idx],
               "repeat": nfm.repeatability(means[list(idx)])[0] * 1e3} for g, idx in GROUPS.items()}
    gap = nfm.angle_diff(circular_mean(means[4:]) - circular_mean(means[:4]), np.pi / 2)
    return {**out, "gap": float(gap) * 1e3}


def pair_theory(grade: str) -> dict[str, float]:
    """Per-pair azimuth 1-sigma (mrad) from the grade's ADEV at the 58 s average, at home and at 90°."""
    nz = load_spec(grade).gyro.noise
    ad = adev_model(DWELL_AVG_S, nz.white, nz.bias_instability, nz.rrw, nz.quantization)
    return {g: pair_azimuth_sigma(ad[0], SITE.latitude, ad[1], np.radians(HOME_AZIMUTH_DEG + off)) * 1e3
            for g, off in (("1-4", 0.0), ("5-7", 90.0))}


def gap_causes(gap_mrad: float) -> dict[str, str]:
    """What a group-mean distance of ``gap_mrad`` would take, by eq. 4.6 (``maytag_azimuth``) at the
    two groups' azimuths (home and home + 90°): a start offset of 90° + e, a y gyro off square with x by
    delta, or an x/y scale-factor mismatch (each alone; first order, checked at 1e-4)."""
    def gap(delta: float = 0.0, mismatch: float = 0.0) -> float:
        errs = []
        for psi in np.radians([HOME_AZIMUTH_DEG, HOME_AZIMUTH_DEG + 90.0]):
            home = np.array([(1 + mismatch / 2) * np.cos(psi), -(1 - mismatch / 2) * np.sin(psi + delta)])
            errs.append(nfm.angle_diff(maytag_azimuth(home, -home), psi))
        return float(errs[1] - errs[0])
    g = gap_mrad * 1e-3
    return {"start offset 90° + e": f"e = {np.degrees(g):.2f}°",
            "x-y non-orthogonality": f"{np.degrees(g / (gap(delta=1e-4) / 1e-4)):.2f}°",
            "x/y scale-factor mismatch": f"{abs(g / (gap(mismatch=1e-4) / 1e-4)) * 1e6:.0f} ppm"}


def simulate_one(proc, spec, truth, seed: int, imperfect: bool, warm_up_scale: float, **options):
    """One power-on of ``truth`` through ``proc``'s sequence on the thesis's site."""
    session, _ = simulate(proc.sequence(spec, **{**proc.DEFAULTS, **options}), truth, seed=seed, site=SITE,
                          imperfections=lab(spec, imperfect, warm_up_scale))
    return session


def table_43(grade: str, reps: int, rate_hz: float, imperfect: bool, warm_up_scale: float = 1.0) -> dict:
    """Per group: per-sequence stds (sliding and disjoint pairs, all repetitions pooled); per repetition the
    repeatability per group and the distance of the two group means (mrad)."""
    spec = replace(load_spec(grade), sample_rate_hz=rate_hz)
    out = {g: {"sliding": [], "disjoint": [], "repeat": [], "theory": []} for g in GROUPS}
    out["gap"] = []
    for r in range(reps):
        truth = draw_unit(spec, 4300 + r)
        sessions = [simulate_one(maytagging, spec, truth, 43_000 + 100 * r + k, imperfect, warm_up_scale,
                                 start_offset_deg=off)
                    for k, off in enumerate(OFFSETS_DEG)]
        fits = {p: [maytagging.analyze(s, grade=spec.name, pairs=p).payload for s in sessions]
                for p in ("sliding", "disjoint")}
        for g, idx in GROUPS.items():
            for p in ("sliding", "disjoint"):
                out[g][p].extend(fits[p][i].unit_std * 1e3 for i in idx)
            out[g]["theory"].extend(fits["sliding"][i].theory["allan_unit_sigma"] * 1e3 for i in idx)
            out[g]["repeat"].append(nfm.repeatability(np.array([fits["sliding"][i].azimuth for i in idx]))[0] * 1e3)
        means = [circular_mean(np.array([fits["sliding"][i].azimuth for i in idx])) for idx in GROUPS.values()]
        out["gap"].append(float(nfm.angle_diff(means[1], means[0])) * 1e3)
    return out


def expected_repeatability(sigma: np.ndarray, draws: int = 20_000) -> np.ndarray:
    """E[max_j |m_j - mean(m)|] (K,) for independent session means m_j ~ N(0, sigma_jk²), ``sigma`` (J, K) rad:
    the repeatability the noise model alone gives (Monte Carlo of ``draws``, fixed seed)."""
    z = np.random.default_rng(0).normal(size=(draws, *sigma.shape)) * sigma
    return np.mean(np.max(np.abs(z - z.mean(axis=1, keepdims=True)), axis=1), axis=0)


def table_44(grade: str, reps: int, rate_hz: float, imperfect: bool, warm_up_scale: float = 1.0) -> dict:
    """Per pairing and repetition: the repeatability over five sessions (8-11 after 1 h, 12 at once), mrad,
    whether session 12 is the farthest, and session 12's pairing mean minus that of 8-11 (mrad)."""
    spec = replace(load_spec(grade), sample_rate_hz=rate_hz)
    out: dict = {"repeat": {}, "farthest_12": [], "shift_12": [], "expected": []}
    for r in range(reps):
        truth = draw_unit(spec, 4400 + r)
        res = [redundant.analyze(simulate_one(redundant, spec, truth, 44_000 + 100 * r + k, imperfect,
                                              warm_up_scale, discard_s=3600.0 if k < 4 else 0.0), grade=spec.name).payload
               for k in range(5)]
        for row in nfm.pairing_table(res):
            out["repeat"].setdefault(row["pairing_deg"], []).append(row["repeatability_mrad"])
        means = np.array([d.detail.mean for d in res])  # (5 sessions, 8 pairings) rad
        dist = np.abs(nfm.angle_diff(means, np.array([circular_mean(m) for m in means.T])))
        out["farthest_12"].append(np.argmax(dist, axis=0) == 4)
        out["shift_12"].append(nfm.angle_diff(means[4], np.array([circular_mean(m) for m in means[:4].T])) * 1e3)
        sigma = np.array([d.theory["pairing_spread"].mean_sigma for d in res])  # (5 sessions, 8 pairings) rad
        out["expected"].append(expected_repeatability(sigma) * 1e3)
    return out


def _calibration(spec, truth, seed: int, imperfect: bool):
    """One power-on's accelerometer model, gyro model (static bias and G, rate M) and its own residuals."""
    imp = lab(spec, imperfect)
    s_mp, _ = simulate(multiposition.sequence(spec, positions=24, dwell_s=60.0), truth, seed=seed, imperfections=imp)
    s_rt, _ = simulate(rate.sequence(spec), truth, seed=seed, imperfections=imp)
    acc, gst, grt = fit_accel(s_mp, warn_hidden_floor=False), fit_gyro_static(s_mp), fit_gyro_rate(s_rt)
    gyro = replace(grt.model(), bias=gst.model().bias, g_sensitivity=gst.model().g_sensitivity)
    return acc, gyro, grt, s_rt


def _after(frame, model: TriadModel, force=None) -> np.ndarray:
    """Residuals (n, 3) of a residual frame's steps compensated with ``model`` (SI)."""
    cols = [f"{k}_{a}" for k in ("ref", "before") for a in "xyz"]
    ref, before = frame[cols[:3]].to_numpy(), frame[cols[3:]].to_numpy()
    return model.compensate(ref + before, force) - ref


def residuals_13(reps: int, rate_hz: float, imperfect: bool) -> dict[str, list[float]]:
    """Largest residuals per repetition: own (calibration session) and validation (next power-on)."""
    spec = replace(load_spec("industrial_mems"), sample_rate_hz=rate_hz)
    fs = spec.gyro.range
    out: dict[str, list[float]] = {"acc_own": [], "acc_val": [], "gyro_own": [], "gyro_val": []}
    for r in range(reps):
        truth = draw_unit(spec, 1300 + r)
        acc1, gyro1, grt1, _ = _calibration(spec, truth, 13_000 + 10 * r, imperfect)
        acc2, _, grt2, s_rt2 = _calibration(spec, truth, 13_000 + 10 * r + 1, imperfect)
        out["acc_own"].append(np.abs(acc1.residuals[["after_x", "after_y", "after_z"]].to_numpy()).max() / MG)
        out["acc_val"].append(np.abs(_after(acc2.residuals, acc1.model())).max() / MG)
        out["gyro_own"].append(np.abs(grt1.residuals[["after_x", "after_y", "after_z"]].to_numpy()).max() / fs * 100)
        steps = [s_rt2.step(int(i)) for i in grt2.residuals["step"]]
        force = np.array([np.asarray(s.mount).T @ np.array([0.0, 0.0, -s_rt2.site.gravity]) for s in steps])
        out["gyro_val"].append(np.abs(_after(grt2.residuals, gyro1, force)).max() / fs * 100)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=10)
    ap.add_argument("--rate-hz", type=float, default=20.0)
    ap.add_argument("--only", default="4.3,4.4,1.3")
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--warm-up-scale", type=float, default=1.0,
                    help="also run the imperfect lab of the ADEV-floor grade with its warm-up times this (what-if)")
    a = ap.parse_args()
    only = set(a.only.split(","))
    # (grade, lab name, imperfect, warm-up scale)
    configs = [(g, name, imp, 1.0) for g in GRADES for name, imp in (("exact", False), ("imperfect", True))]
    if a.warm_up_scale != 1.0:
        configs.append((GRADES[1], f"imperfect, warm-up x{a.warm_up_scale:g}", True, a.warm_up_scale))
    t0 = time.process_time()
    lines = [f"Seed vs virtual lab, {a.reps} repetitions, cells = median [min-max] over the repetitions "
             f"(per-sequence std: over all sequences of all repetitions); samples at {a.rate_hz:g} Hz.", ""]

    def emit(text: str) -> None:
        lines.append(text)
        print(text, flush=True)

    if "4.3" in only:
        seed = thesis_43()
        emit("## Thesis table 4.3: maytagging, mrad")
        emit("")
        emit("Per-sequence std of the azimuths (one every 60 s from overlapping pairs, as the thesis; then from "
             "disjoint pairs), the per-pair theory (grade ADEV at 58 s), the repeatability (largest distance of a "
             "sequence mean from its group mean) and the group gap (5-7 mean minus 1-4 mean, 90° removed).")
        emit("")
        emit("| source | lab | std 1-4 | std 5-7 | disjoint 1-4 | disjoint 5-7 | theory 1-4 / 5-7 | with dead time | "
             "repeat. 1-4 | "
             "repeat. 5-7 | group gap |")
        emit("|---|---|---|---|---|---|---|---|---|---|---|")
        emit(f"| thesis (table 4.3) | real | {cell(seed['1-4']['std'])} | {cell(seed['5-7']['std'])} | | | | | "
             f"{seed['1-4']['repeat']:.2f} (text {THESIS_43_STATED['1-4']}) | "
             f"{seed['5-7']['repeat']:.2f} (text {THESIS_43_STATED['5-7']}) | {seed['gap']:+.1f} |")
        for grade, name, imperfect, scale in configs:
            th, t43 = pair_theory(grade), table_43(grade, a.reps, a.rate_hz, imperfect, scale)
            emit(f"| {grade} | {name} | {cell(t43['1-4']['sliding'])} | "
                 f"{cell(t43['5-7']['sliding'])} | {cell(t43['1-4']['disjoint'])} | "
                 f"{cell(t43['5-7']['disjoint'])} | {th['1-4']:.2f} / {th['5-7']:.2f} | "
                 f"{np.median(t43['1-4']['theory']):.2f} / {np.median(t43['5-7']['theory']):.2f} | "
                 f"{cell(t43['1-4']['repeat'])} | {cell(t43['5-7']['repeat'])} | {cell(t43['gap'])} |")
        emit("")
        emit(f"What the thesis's group gap ({seed['gap']:+.1f} mrad) would take, each alone (eq. 4.6 at "
             f"{HOME_AZIMUTH_DEG:.2f}° and {HOME_AZIMUTH_DEG + 90:.2f}°): "
             + "; ".join(f"{k}: {v}" for k, v in gap_causes(seed["gap"]).items()) + ".")
        emit("")
    if "4.4" in only:
        results = {(g, name): table_44(g, a.reps, a.rate_hz, imp, scale) for g, name, imp, scale in configs}
        seed = np.array(list(THESIS_44.values()))
        emit("## Thesis table 4.4: redundant configuration, repeatability per pairing, mrad")
        emit("")
        emit("| pairing | thesis | " + " | ".join(f"{g.replace('cvg_two_axis', 'cvg')} {name}"
                                               for g, name in results) + " |")
        emit("|---" * (len(results) + 2) + "|")
        for pairing, value in THESIS_44.items():
            emit(f"| {pairing}° | {value:.2f} | " + " | ".join(cell(r["repeat"][pairing]) for r in results.values())
                 + " |")
        medians = {k: np.array([np.median(v) for v in r["repeat"].values()]) for k, r in results.items()}
        emit(f"| all (range) | {seed.min():.2f}-{seed.max():.2f} | " + " | ".join(
            f"{m.min():.2f}-{m.max():.2f}" for m in medians.values()) + " |")
        emit("| correlation with the thesis | 1 | " + " | ".join(
            f"{np.corrcoef(seed, m)[0, 1]:+.2f}" for m in medians.values()) + " |")
        emit("| noise model alone, bias wander included (range over the pairings) | | " + " | ".join(
            f"{np.median(r['expected'], axis=0).min():.2f}-{np.median(r['expected'], axis=0).max():.2f}"
            for r in results.values()) + " |")
        emit("| session 12 the farthest [% of pairings] | | " + " | ".join(
            f"{100 * np.mean(r['farthest_12']):.0f}" for r in results.values()) + " |")
        emit("")
        emit("Sequence 12's warm-up shift per pairing (its pairing mean minus that of 8-11, imperfect minus exact "
             "lab on the same seeds, median over the repetitions), mrad, and its correlation with the thesis:")
        emit("")
        emit("| grade | lab | " + " | ".join(f"{p}°" for p in THESIS_44) + " | correlation of abs. with thesis |")
        emit("|---" * (len(THESIS_44) + 3) + "|")
        for g, name, imperfect, _ in configs:
            if imperfect:
                shift = np.median(np.array(results[(g, name)]["shift_12"]) -
                                  np.array(results[(g, "exact")]["shift_12"]), axis=0)
                emit(f"| {g} | {name} | " + " | ".join(f"{v:+.2f}" for v in shift) +
                     f" | {np.corrcoef(seed, np.abs(shift))[0, 1]:+.2f} |")
        emit("")
    if "1.3" in only:
        emit("## Thesis sec. 1.3: largest residuals after calibration, industrial_mems")
        emit("")
        emit("| lab | accel own [mg] | accel next power-on [mg] | thesis | gyro own [% FS] | "
             "gyro next power-on [% FS] | thesis |")
        emit("|---|---|---|---|---|---|---|")
        for imperfect in (False, True):
            r = residuals_13(a.reps, a.rate_hz, imperfect)
            emit(f"| {'imperfect' if imperfect else 'exact'} | {cell(r['acc_own'])} | {cell(r['acc_val'])} | < 17 | "
                 f"{cell(r['gyro_own'])} | {cell(r['gyro_val'])} | < 0.7 |")
        emit("")
    emit(f"_{time.process_time() - t0:.0f} s CPU_")
    if a.out is not None:
        a.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
