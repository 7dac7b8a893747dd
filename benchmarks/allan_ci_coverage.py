"""Monte Carlo coverage of the stability family's confidence intervals, per noise type and statistic.

For each power-law noise (white PM, flicker PM, white FM, flicker FM, random-walk FM;
:func:`workbench.sim.powerlaw.power_law_phase`, fixed seeds) ``--records`` phase records of
``--n`` points are analysed by :func:`workbench.analysis.stability.stability` and
:func:`workbench.analysis.stability_ci.intervals` (noise identified as in use, 95 %). The
reference value at each tau is the root of the Monte Carlo mean of the variance over all
records (the estimator's expectation; its own error sqrt(2 / (R edf)) is far inside the
intervals). Coverage is pooled over the taus with m <= n / 10; the binomial 95 % band for k
pooled intervals is 0.95 +- 1.96 sqrt(0.0475 / k) (wider in truth: neighbouring taus share data).

    python benchmarks/allan_ci_coverage.py [--n 1024] [--records 400] [--stats oadev,mdev,...]

Prints a table: statistic x noise type, coverage, the binomial band, OK / LOW / HIGH against it,
and a "!" where the coverage is outside the target 95 +- 2 %.
"""

from __future__ import annotations

import argparse

import numpy as np

from workbench.analysis.stability import stability
from workbench.analysis.stability_ci import intervals
from workbench.sim.powerlaw import NOISE_NAMES, power_law_phase

TARGET = 0.02  # coverage target: 95 +- 2 %
DEFAULT_STATS = "adev,oadev,mdev,tdev,hdev,ohdev,totdev,mtotdev,ttotdev,htotdev,theo1"


def coverage(stat: str, alpha: int, n: int, records: int, seed: int, level: float = 0.95) -> tuple[float, int]:
    """(coverage, number of pooled intervals) of ``stat`` on ``records`` records of noise ``alpha``."""
    x = power_law_phase(alpha, n, records, np.random.default_rng(seed))
    devs, los, his, m = [], [], [], None
    for rec in x:
        s = stability(rec, 1.0, stat, "phase", "octave")
        ci = intervals(s, rec, level)
        m = s.m
        devs.append(s.dev)
        los.append(ci.lo)
        his.append(ci.hi)
    dev, lo, hi = np.array(devs), np.array(los), np.array(his)
    truth = np.sqrt(np.mean(dev ** 2, axis=0))
    use = m <= n / 10
    covered = (lo[:, use] <= truth[use]) & (truth[use] <= hi[:, use])
    return float(covered.mean()), int(covered.size)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1024, help="phase points per record")
    ap.add_argument("--records", type=int, default=400, help="records per noise type and statistic")
    ap.add_argument("--stats", default=DEFAULT_STATS)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    print(f"95 % interval coverage, {args.records} records of {args.n} phase points, taus m <= n/10")
    print(f"{'stat':8s} " + " ".join(f"{NOISE_NAMES[a]:>23s}" for a in NOISE_NAMES))
    for stat in args.stats.split(","):
        cells = []
        for alpha in NOISE_NAMES:
            cov, k = coverage(stat, alpha, args.n, args.records, args.seed + 10 * alpha + 100)
            band = 1.96 * np.sqrt(0.0475 / k)
            flag = "OK" if abs(cov - 0.95) <= band else ("LOW" if cov < 0.95 else "HIGH")
            cells.append(f"{cov:6.3f} (+-{band:.3f}) {flag:4s}{'!' if abs(cov - 0.95) > TARGET else ' '}")
        print(f"{stat:8s} " + " ".join(f"{c:>23s}" for c in cells), flush=True)


if __name__ == "__main__":
    main()
