"""Monte Carlo EDF of the total and Theo statistics against the EDF in use and the EDF Stable32 used.

For each statistic and power-law noise (:func:`workbench.sim.powerlaw.power_law_phase`, fixed seeds),
``--records`` phase records of ``--n`` points (default 1001, PHASE.DAT's length) give at every
octave m the Monte Carlo EDF 2 E[s^2]^2 / var(s^2) of the variance estimates s^2 (relative
standard error about sqrt((2 + 12 / edf) / R) for R records). Beside it: ours
(:func:`workbench.analysis.stability_ci.edf_of`) and, where a Stable32 table for PHASE.DAT
(/work/shared/data/allantools_reference, README there) has that m with that noise type, the EDF
its 1-sigma bounds imply, inverted with Stable32's own chi-squared quantiles (Abramowitz & Stegun
26.4.17 with 26.2.22 above 100 EDF, its a1 digit swap included; exact below).

    python benchmarks/allan_ci_edf.py [--stats totdev,mtotdev,htotdev,theo1] [--n 1001] [--records 1000]
"""

from __future__ import annotations

import argparse
from math import erf, sqrt
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

from workbench.analysis.chi2 import chi2_ppf
from workbench.analysis.stability import stability
from workbench.analysis.stability_ci import edf_of
from workbench.sim.powerlaw import NOISE_NAMES, power_law_phase

REF = Path("/work/shared/data/allantools_reference/phasedat")
ONE_SIGMA = erf(1.0 / sqrt(2.0))  # Stable32's "0.683"


def chi2_stable32(p: float, edf: float) -> float:
    """Stable32's chi-squared quantile at lower-tail probability ``p``."""
    if edf <= 100:
        return float(chi2_ppf(p, edf))
    t = sqrt(-2.0 * np.log(min(p, 1.0 - p)))
    xp = t - (2.30753 + 0.27601 * t) / (1.0 + 0.99229 * t + 0.04481 * t * t)
    xp = -xp if p < 0.5 else xp
    return edf * (1.0 - 2.0 / (9.0 * edf) + xp * sqrt(2.0 / (9.0 * edf))) ** 3


def stable32_edf(ratio_hi: float) -> float:
    """EDF whose Stable32 1-sigma upper bound is ``ratio_hi`` times the deviation."""
    q = (1.0 - ONE_SIGMA) / 2.0
    return brentq(lambda e: sqrt(e / chi2_stable32(q, e)) - ratio_hi, 0.05, 1e5)


def stable32_table(stat: str) -> dict[tuple[int, int], float]:
    """{(m, alpha): implied EDF} over Stable32's bounded tables of ``stat`` (commented rows included)."""
    out = {}
    for f in sorted(REF.glob(f"phase_dat_{stat}*.txt")):
        for line in f.read_text("latin-1").splitlines():
            v = line.lstrip("# ").split()
            try:
                m, _, _, a, lo, dev, hi = (float(t) for t in v)
            except ValueError:
                continue
            if lo > 0:
                out.setdefault((int(m), int(a)), stable32_edf(hi / dev))
    return out


def mc_edf(stat: str, alpha: int, n: int, records: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(m, Monte Carlo EDF) of ``stat`` at the octave factors for noise ``alpha``."""
    x = power_law_phase(alpha, n, records, np.random.default_rng(seed))
    v, m = [], None
    for rec in x:
        s = stability(rec, 1.0, stat, "phase", "octave")
        v.append(s.dev ** 2)
        m = s.m
    v = np.array(v)
    return m, 2.0 * v.mean(axis=0) ** 2 / v.var(axis=0, ddof=1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stats", default="totdev,mtotdev,htotdev,theo1")
    ap.add_argument("--n", type=int, default=1001, help="phase points per record")
    ap.add_argument("--records", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1000)
    args = ap.parse_args()
    print(f"EDF: Monte Carlo ({args.records} records of {args.n} points) / ours / Stable32 (PHASE.DAT, N = 1001)")
    for stat in args.stats.split(","):
        s32 = stable32_table(stat) if args.n == 1001 else {}
        for alpha in NOISE_NAMES:
            m, mc = mc_edf(stat, alpha, args.n, args.records, args.seed + alpha)
            cells = []
            for mk, e in zip(m, mc):
                ours = edf_of(stat, alpha, int(mk), args.n)
                ref = s32.get((int(mk), alpha))
                cells.append(f"{int(mk)}: {e:.1f}/{ours:.1f}" + (f"/{ref:.1f}" if ref else ""))
            print(f"{stat:8s} {NOISE_NAMES[alpha]:15s} " + "  ".join(cells), flush=True)


if __name__ == "__main__":
    main()
