"""GMWM against the IEEE 952 Allan fit on the virtual lab's grades: bias, rms and interval coverage per term.

Gyro (and, with ``--triads gyro,accel``, accelerometer) records of every chosen grade come from
the virtual sensor's noise chain (:func:`benchmarks.allan_coverage.simulate`: white, flicker
bias instability, RRW, integrated quantizer, output rounding; truth from
:func:`benchmarks.allan_coverage.truth_of`), one axis per seed. Both fits run on the same record:
:func:`workbench.analysis.allan_fit.analyze_record` (IEEE 952) and
:func:`workbench.analysis.gmwm.fit_gmwm` with ``--model`` (auto: wn+fl+rw, +qn where the grade
quantizes). Per grade, record length, triad, term and method: bias = mean(estimate / truth) - 1
and rms = sqrt(mean((estimate / truth - 1)^2)) over the records where the term is observed, the
share of records whose 95 % interval ([0, upper limit] when not observed) holds the truth, and
how many records observed the term. Coverage over S seeds has a binomial sigma
sqrt(0.95 x 0.05 / S) (0.022 at S = 100).

Figures reported (docs/allan.md, GMWM): ``--seeds 20 --hours 1`` over ten grades (gyro), not
100 seeds: the shared 2-core machine ran at load ~15-20 (2-6 min per grade at 20 seeds).
Coverage over 20 seeds has a binomial sigma of 0.049. Not met: inav_fms (Q 0.485 urad at 200 Hz)
GMWM puts a third of the quantization into N (coverage 0 for both), RRW coverage 0.10.

    python benchmarks/allan_gmwm_vs_ieee.py [--seeds 100] [--hours 1,0.25] [--grades all|industrial_mems,...]
        [--triads gyro] [--model auto] [--bootstrap 100]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from benchmarks.allan_coverage import simulate, truth_of
from workbench.analysis.allan_fit import analyze_record
from workbench.analysis.gmwm import fit_gmwm
from workbench.grades import grade_names, load_spec

TERMS = ("white", "bias_instability", "rrw", "quantization")


def auto_model(noise) -> str:
    """wn+fl+rw, plus qn when the grade quantizes its integrated output."""
    return "wn+fl+rw" + ("+qn" if float(np.max(noise.quantization)) > 0 else "")


def run(grade: str, triad: str, seeds: int, hours: float, model: str, bootstrap: int) -> dict:
    """{(term, method): [(ratio or NaN when not observed, covered), ...]} over ``seeds`` records."""
    spec = load_spec(grade)
    ts, rate = spec.specs.get(triad), spec.sample_rate_hz
    if ts is None:
        return {}
    truth = truth_of(ts.noise, rate)
    axis = int(list(ts.sensing_axes)[0])
    out: dict = {}
    for seed in range(1, seeds + 1):
        y = simulate(ts.noise, rate, hours, 1000 * seed + 7)[:, axis:axis + 1]
        ieee = analyze_record(y, rate, ["c"], None).fits[0].terms
        gm = fit_gmwm(y[:, 0], rate, auto_model(ts.noise) if model == "auto" else model, "c",
                      bootstrap=bootstrap, seed=seed)
        for term in TERMS:
            t_true = float(truth[term][axis])
            if t_true <= 0:
                continue
            t = ieee[term]
            lo, hi = t.ci95
            out.setdefault((term, "ieee952"), []).append((t.value / t_true if t.observed else np.nan,
                                                           lo <= t_true <= hi))
            if term in gm.terms:
                v, lo, hi = gm.terms[term]
                out.setdefault((term, "gmwm"), []).append((v / t_true if gm.resolved[term] else np.nan,
                                                           lo <= t_true <= hi))
    return out


def _stats(rows: list) -> str:
    r = np.array([x[0] for x in rows], float)
    ok = np.isfinite(r)
    bias = float(np.mean(r[ok]) - 1) if ok.any() else np.nan
    rms = float(np.sqrt(np.mean((r[ok] - 1) ** 2))) if ok.any() else np.nan
    return f"{bias:+8.4f} {rms:7.4f} {np.mean([x[1] for x in rows]):6.2f} {int(ok.sum()):4d}"


def main() -> None:
    """Command-line entry: the side-by-side table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--hours", default="1")
    ap.add_argument("--grades", default="all")
    ap.add_argument("--triads", default="gyro")
    ap.add_argument("--model", default="auto", help="GMWM model, or auto (wn+fl+rw, +qn for a quantizing grade)")
    ap.add_argument("--bootstrap", type=int, default=100)
    a = ap.parse_args()
    grades = grade_names() if a.grades == "all" else a.grades.split(",")
    print(f"{a.seeds} seeds per grade, record length and triad; GMWM model {a.model}, bootstrap {a.bootstrap}; "
          f"binomial sigma of a coverage {np.sqrt(0.95 * 0.05 / a.seeds):.3f}")
    head = f"{'bias':>8s} {'rms':>7s} {'cover':>6s} {'obs':>4s}"
    print(f"{'grade':26s} {'h':>5s} {'triad':5s} {'term':17s} | GMWM {head} | IEEE 952 {head}")
    for g in grades:
        for hours in (float(h) for h in a.hours.split(",")):
            for triad in a.triads.split(","):
                t0 = time.perf_counter()
                res = run(g, triad, a.seeds, hours, a.model, a.bootstrap)
                for term in TERMS:
                    if (term, "ieee952") in res:
                        gm = _stats(res[(term, "gmwm")]) if (term, "gmwm") in res else "(not in the model)"
                        print(f"{g:26s} {hours:5g} {triad:5s} {term:17s} | GMWM {gm} | IEEE 952 "
                              f"{_stats(res[(term, 'ieee952')])}", flush=True)
                print(f"  ({time.perf_counter() - t0:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
