"""GMWM against the IEEE 952 Allan fit on the virtual lab's grades: bias and rms of each term.

Gyro records of every chosen grade come from the virtual sensor's noise chain
(:func:`benchmarks.allan_coverage.simulate`: white, flicker bias instability, RRW, quantizer,
output rounding; truth from :func:`benchmarks.allan_coverage.truth_of`), one axis per seed.
Both fits run on the same record: :func:`workbench.analysis.allan_fit.analyze_record` (IEEE 952;
a term not observed counts as missing) and :func:`workbench.analysis.gmwm.fit_gmwm` with
``--model`` (B from the Gauss-Markov plateau). Per grade, method and term: median and rms of
log(estimate / truth) as a ratio (exp), the share of records whose 95 % interval holds the
truth, and how many records gave a value.

    python benchmarks/allan_gmwm_vs_ieee.py [--seeds 100] [--hours 1] [--grades industrial_mems,hg1700]
        [--model auto|wn+2gm+rw|...] [--bootstrap 30]
"""

from __future__ import annotations

import argparse

import numpy as np

from benchmarks.allan_coverage import simulate, truth_of
from workbench.analysis.allan_fit import analyze_record
from workbench.analysis.gmwm import fit_gmwm
from workbench.grades import load_spec

TERMS = ("white", "bias_instability", "rrw")


def _model(model: str, noise) -> str:
    """``auto``: wn+2gm+rw, plus qn when the grade quantizes its output."""
    if model != "auto":
        return model
    return "wn+2gm+rw" + ("+qn" if float(np.max(noise.quantization)) > 0 else "")


def run(grade: str, seeds: int, hours: float, model: str, bootstrap: int) -> dict:
    """{(method, term): [(ratio, covered), ...]} over ``seeds`` gyro records of ``grade``."""
    spec = load_spec(grade)
    ts, rate = spec.specs["gyro"], spec.sample_rate_hz
    truth = truth_of(ts.noise, rate)
    out: dict = {}
    for seed in range(1, seeds + 1):
        y = simulate(ts.noise, rate, hours, 1000 * seed + 7)[:, :1]
        ieee = analyze_record(y, rate, ["gx"], None).fits[0].terms
        gm = fit_gmwm(y[:, 0], rate, _model(model, ts.noise), "gx", bootstrap=bootstrap, seed=seed)
        for term in TERMS:
            t_true = float(truth[term][0])
            if t_true <= 0:
                continue
            t = ieee[term]
            lo, hi = t.ci95
            out.setdefault(("ieee952", term), []).append((t.value / t_true if t.observed else np.nan,
                                                           lo <= t_true <= hi))
            if term in gm.terms:
                v, lo, hi = gm.terms[term]
                out.setdefault(("gmwm", term), []).append((v / t_true, lo <= t_true <= hi))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--grades", default="industrial_mems,quasi_tactical,hg1700")
    ap.add_argument("--model", default="auto", help="GMWM model, or auto (wn+2gm+rw, +qn for a quantizing grade)")
    ap.add_argument("--bootstrap", type=int, default=30)
    a = ap.parse_args()
    print(f"gyro, {a.seeds} seeds x {a.hours:g} h per grade; GMWM model {a.model}, bootstrap {a.bootstrap}")
    print(f"{'grade':18s} {'method':8s} {'term':17s} {'median':>7s} {'rms':>7s} {'coverage':>8s} {'n':>4s}")
    for g in a.grades.split(","):
        for (method, term), rows in sorted(run(g, a.seeds, a.hours, a.model, a.bootstrap).items()):
            r = np.array([x[0] for x in rows], float)
            ok = np.isfinite(r) & (r > 0)
            lr = np.log(r[ok])
            med = float(np.exp(np.median(lr))) if ok.any() else float("nan")
            rms = float(np.exp(np.sqrt(np.mean(lr ** 2)))) if ok.any() else float("nan")
            cov = float(np.mean([x[1] for x in rows]))
            print(f"{g:18s} {method:8s} {term:17s} {med:7.3f} {rms:7.3f} {cov:8.2f} {int(ok.sum()):4d}", flush=True)


if __name__ == "__main__":
    main()
