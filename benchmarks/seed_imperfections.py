"""Thesis tables 4.3, 4.4 and the sec. 1.3 residuals through a virtual lab as imperfect as real units.

Seed: ``shared/seeds/000_*`` (thesis). Every figure is printed beside the seed's, for the
model-exact virtual lab ("exact") and with the imperfections switched on ("imperfect": the
grade's ``imperfections`` block, all groups, plus the table errors below), over ``--reps``
repetitions (each a fresh unit; each sequence of a repetition a fresh power-on of that unit,
as the thesis turns the unit off for an hour between sequences). Cells: median [min-max]
over the repetitions.

1. Table 4.3 (maytagging, sequences 1-4 at the home position, 5-7 at 90°; 40 pairs x 60 s,
   measured from power-on): the per-sequence std of the 40 azimuths (mrad; thesis 6.75-9.47
   for 1-4, 5.83-8.80 for 5-7) and the repeatability, the largest distance of a sequence mean
   from the group mean (thesis 2.4 / 0.75 mrad). Grades ``cvg_two_axis`` (table 4.1 read as
   the IEEE 952 B) and ``cvg_two_axis_adev_floor`` (read as the ADEV floor).
2. Table 4.4 (redundant configuration, sequences 8-12: 10 turns of 45° steps; 8-11 after one
   hour of warm-up, 12 at once): per pairing, the largest distance of a session's pairing
   mean from the mean over the five sessions (thesis 3.34-12.49 mrad).
3. Sec. 1.3 residuals (``industrial_mems``, the AX1-GNS3 class): a calibration session
   (24 positions x 60 s, then the rate procedure) and a second power-on compensated with its
   coefficients: the largest accelerometer residual (mg; thesis < 17 mg) and gyro residual
   (% of full scale; thesis < 0.7 %), beside the calibration session's own residuals.

Table errors of the imperfect lab (chosen: a mid-range positioning table, not the thesis's,
which gives none): indexing error 0.01°, wobble 0.003°, axis tilt 0.02°.
Samples are simulated at ``--rate-hz`` (default 20 Hz) to keep the run short: every figure
here is a mean over >= 58 s, which depends on the noise densities, not on the sample rate.

Usage: ``python benchmarks/seed_imperfections.py [--reps 10] [--rate-hz 20] [--only 4.3,4.4,1.3]
[--out FILE]``.
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
from workbench.analysis.turntable import fit_accel, fit_gyro_rate, fit_gyro_static
from workbench.grades import draw_unit, load_spec
from workbench.jobs import simulate
from workbench.model import TriadModel
from workbench.sim.imperfections import Imperfections

TABLE = {"table_indexing_error": np.radians(0.01), "table_wobble": np.radians(0.003),
         "table_axis_tilt": np.radians(0.02)}
MG = 9.80665e-3
THESIS_43 = {"1-4": ("6.75-9.47", 2.4), "5-7": ("5.83-8.80", 0.75)}
THESIS_44 = {"0-45": 6.63, "45-90": 12.49, "90-135": 6.18, "135-180": 3.34, "180-225": 3.46, "225-270": 8.46,
             "270-315": 9.56, "315-0": 4.17}


def lab(spec, imperfect: bool) -> Imperfections | None:
    """The imperfections of the imperfect lab for ``spec`` (None: the model-exact lab)."""
    return Imperfections.from_spec(spec, "all", **TABLE) if imperfect else None


def cell(values) -> str:
    """median [min-max] of the repetitions."""
    v = np.asarray(values, float)
    return f"{np.median(v):.2f} [{v.min():.2f}-{v.max():.2f}]"


def run(proc, spec, truth, seed: int, imperfect: bool, **options):
    """One power-on of ``truth``: simulate and analyse ``proc``; its NorthFinding payload."""
    session, _ = simulate(proc.sequence(spec, **{**proc.DEFAULTS, **options}), truth, seed=seed,
                          imperfections=lab(spec, imperfect))
    return proc.analyze(session, grade=spec.name).payload


def table_43(grade: str, reps: int, rate_hz: float, imperfect: bool) -> dict:
    """Per group: per-sequence stds (all repetitions pooled) and the repeatability per repetition."""
    spec = replace(load_spec(grade), sample_rate_hz=rate_hz)
    out = {"1-4": ([], []), "5-7": ([], [])}
    for r in range(reps):
        truth = draw_unit(spec, 4300 + r)
        seqs = [run(maytagging, spec, truth, 43_000 + 100 * r + k, imperfect, start_offset_deg=off)
                for k, off in enumerate([0, 0, 0, 0, 90, 90, 90])]
        for group, idx in (("1-4", range(0, 4)), ("5-7", range(4, 7))):
            rows = nfm.sequence_table([seqs[i] for i in idx])
            out[group][0].extend(row["std_mrad"] for row in rows)
            out[group][1].append(max(abs(row["distance_mrad"]) for row in rows))
    return out


def table_44(grade: str, reps: int, rate_hz: float, imperfect: bool) -> dict[str, list[float]]:
    """Per pairing: the repeatability over five sessions (8-11 after 1 h, 12 at once), per repetition."""
    spec = replace(load_spec(grade), sample_rate_hz=rate_hz)
    out: dict[str, list[float]] = {}
    for r in range(reps):
        truth = draw_unit(spec, 4400 + r)
        res = [run(redundant, spec, truth, 44_000 + 100 * r + k, imperfect, discard_s=3600.0 if k < 4 else 0.0)
               for k in range(5)]
        for row in nfm.pairing_table(res):
            out.setdefault(row["pairing_deg"], []).append(row["repeatability_mrad"])
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
    a = ap.parse_args()
    only = set(a.only.split(","))
    t0 = time.process_time()
    lines = [f"Seed vs virtual lab, {a.reps} repetitions, cells = median [min-max] over the repetitions "
             f"(per-sequence std: over all sequences of all repetitions); samples at {a.rate_hz:g} Hz.", ""]

    def emit(text: str) -> None:
        lines.append(text)
        print(text, flush=True)

    if "4.3" in only:
        emit("## Thesis table 4.3: maytagging (per-sequence std, repeatability), mrad")
        emit("")
        emit("| grade | lab | std 1-4 | thesis | std 5-7 | thesis | repeat. 1-4 | thesis | repeat. 5-7 | thesis |")
        emit("|---|---|---|---|---|---|---|---|---|---|")
        for grade in ("cvg_two_axis", "cvg_two_axis_adev_floor"):
            for imperfect in (False, True):
                t = table_43(grade, a.reps, a.rate_hz, imperfect)
                emit(f"| {grade} | {'imperfect' if imperfect else 'exact'} | {cell(t['1-4'][0])} | "
                     f"{THESIS_43['1-4'][0]} | {cell(t['5-7'][0])} | {THESIS_43['5-7'][0]} | {cell(t['1-4'][1])} | "
                     f"{THESIS_43['1-4'][1]} | {cell(t['5-7'][1])} | {THESIS_43['5-7'][1]} |")
        emit("")
    if "4.4" in only:
        grades = ("cvg_two_axis", "cvg_two_axis_adev_floor")
        results = {(g, imp): table_44(g, a.reps, a.rate_hz, imp) for g in grades for imp in (False, True)}
        emit("## Thesis table 4.4: redundant configuration, repeatability per pairing, mrad")
        emit("")
        emit("| pairing | thesis | " + " | ".join(f"{g.replace('cvg_two_axis', 'cvg')} {'imperfect' if i else 'exact'}"
                                               for g, i in results) + " |")
        emit("|---" * (len(results) + 2) + "|")
        for pairing, seed in THESIS_44.items():
            emit(f"| {pairing}° | {seed:.2f} | " + " | ".join(cell(r[pairing]) for r in results.values()) + " |")
        emit(f"| all (range) | 3.34-12.49 | " + " | ".join(
            f"{min(np.median(v) for v in r.values()):.2f}-{max(np.median(v) for v in r.values()):.2f}"
            for r in results.values()) + " |")
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
