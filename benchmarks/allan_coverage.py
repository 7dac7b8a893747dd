"""Monte Carlo coverage of the IEEE 952 fit's 95 % intervals over the virtual lab's grades.

Records come from the virtual sensor's noise chain (:class:`workbench.sim.noise.NoiseProcess`,
the integrated quantizer and the output rounding, as :mod:`workbench.sim.sensor` applies them)
with each grade's gyro and accel terms; every axis of every record is fitted by
:func:`workbench.analysis.allan_fit.analyze_record` and each term's reported interval (fitted
or "not observed" [0, bound]) is checked against the simulated value (rate ramp: 0).

    python benchmarks/allan_coverage.py --seeds 20 --hours 2 [--grades quasi_tactical,hg1700]

Prints per grade and term the coverage and, for observed terms, the median ratio to truth.
A binomial 95 % band on the coverage with n intervals is 0.95 +- 1.96 sqrt(0.0475 / n).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from workbench.analysis.allan_fit import TERMS, analyze_record
from workbench.grades import grade_names, load_spec
from workbench.sim.noise import IntegratedQuantizer, NoiseProcess, round_to_resolution


def simulate(noise, rate: float, hours: float, seed: int) -> np.ndarray:
    """(n, 3) noise record of one triad (SI) through the virtual sensor's noise chain."""
    n = int(hours * 3600 * rate)
    y = NoiseProcess(noise.white, noise.bias_instability, noise.rrw, 1.0 / rate, seed).generate(n)
    return round_to_resolution(IntegratedQuantizer(noise.quantization, 1.0 / rate).apply(y), noise.resolution)


def truth_of(noise, rate: float) -> dict[str, np.ndarray]:
    """Simulated value of each term (SI, per axis); the output rounding to the LSB r adds white
    noise of variance r^2 / 12 per sample (density^2 r^2 / 12 / rate)."""
    white = np.sqrt(noise.white ** 2 + noise.resolution ** 2 / 12.0 / rate)
    return {"quantization": noise.quantization, "white": white, "bias_instability": noise.bias_instability,
            "rrw": noise.rrw, "rate_ramp": np.zeros(3)}


def run(grades: list[str], seeds: int, hours: float) -> dict:
    """Coverage counts {(grade, triad, term): [covered, total, ratios...]}."""
    stats: dict = {}
    for g in grades:
        spec = load_spec(g)
        for triad in ("gyro", "accel"):
            ts = spec.specs.get(triad)
            if ts is None:
                continue
            axes = list(ts.sensing_axes)
            truth = truth_of(ts.noise, spec.sample_rate_hz)
            for seed in range(1, seeds + 1):
                y = simulate(ts.noise, spec.sample_rate_hz, hours, 1000 * seed + 7)[:, axes]
                an = analyze_record(y, spec.sample_rate_hz, [f"c{j}" for j in axes], None)
                for j, fit in zip(axes, an.fits):
                    for term in TERMS:
                        t = fit.terms[term]
                        lo, hi = t.ci95
                        s = stats.setdefault((g, triad, term), [0, 0, []])
                        s[0] += int(lo <= truth[term][j] <= hi)
                        s[1] += 1
                        if t.observed and truth[term][j] > 0:
                            s[2].append(t.value / truth[term][j])
    return stats


def main() -> None:
    """Command-line entry: print the coverage table."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument("--hours", type=float, default=2.0)
    p.add_argument("--grades", default=",".join(grade_names()))
    a = p.parse_args()
    t0 = time.perf_counter()
    stats = run(a.grades.split(","), a.seeds, a.hours)
    cov, tot = 0, 0
    print(f"{'grade':22s} {'triad':5s} {'term':17s} coverage  n   median est/truth (observed)")
    for (g, triad, term), (c, n, ratios) in stats.items():
        cov, tot = cov + c, tot + n
        med = f"{np.median(ratios):.3f} ({len(ratios)})" if ratios else "-"
        flag = "" if abs(c / n - 0.95) <= 1.96 * np.sqrt(0.0475 / n) + 1e-9 else "  <-- outside binomial band"
        print(f"{g:22s} {triad:5s} {term:17s} {c / n:7.3f} {n:4d}   {med}{flag}")
    print(f"overall coverage {cov / tot:.4f} over {tot} intervals ({a.seeds} seeds, {a.hours} h records); "
          f"{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
