"""North-finding benchmark through the simulator (two-axis CVG, 40.8°): achieved vs theoretical.

Tables (markdown, printed and written to ``--out``):

1. maytagging accuracy, 40 pairs x 60 s: white noise only (``--seeds`` seeds, pooled per-pair
   std vs ARW theory, mean error) and the full grade (thesis table 4.3: 4 sequences at the
   home position, 3 at 90°, per-pair std vs Allan theory, repeatability as Fig. 4.14-4.15);
2. dwell time and ordering (ABAB / ABBA) at equal total time (80 min): per-pair std, RMS
   error of the sequence mean against the theory;
3. carousel: RMS error vs number of laps against the ARW theory;
4. redundant configuration: 5 sessions of 10 turns, thesis table 4.4.

Usage: ``python benchmarks/northfinding_sweep.py [--seeds 10] [--out table.md] [--quick]``
(``--quick``: fewer seeds and dwell times, a few minutes on one core).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import procedures.carousel as carousel
import procedures.maytagging as maytagging
import procedures.redundant as redundant
from workbench.analysis import northfinding as nfm
from workbench.analysis import northfinding_theory as th
from workbench.grades import load_spec
from workbench.jobs import simulate

TOTAL_S = 4800.0  # s, 40 pairs x 2 x 60 s


def white_only(spec):
    """The grade with its gyro bias instability and rate random walk removed."""
    g = spec.specs["gyro"]
    noise = replace(g.noise, bias_instability=np.zeros(3), rrw=np.zeros(3))
    return replace(spec, specs={**spec.specs, "gyro": replace(g, noise=noise)})


def run(proc, spec, seed, **options):
    """Simulate one procedure and find north with the grade ``spec`` itself (a modified grade has no name the
    procedure's ``grade`` option could take); returns the NorthFinding."""
    session, _ = simulate(proc.sequence(spec, **{**proc.DEFAULTS, **options}), spec, seed=seed)
    return nfm.find_north(session, proc.NAME, settle_s=float(session.options.get("settle_s", 2.0)), grade=spec)


def pooled(results):
    """Pooled per-unit std about the truth (rad), RMS of the mean errors (rad), mean theories (rad)."""
    dev = np.concatenate([nfm.angle_diff(r.unit_azimuth, r.true_azimuth) for r in results])
    err = np.array([r.azimuth_error for r in results])
    arw = np.sqrt(np.mean([r.theory["arw_unit_sigma"] ** 2 for r in results]))
    allan = np.sqrt(np.mean([r.theory["allan_unit_sigma"] ** 2 for r in results]))
    return float(np.std(dev)), float(np.sqrt(np.mean(err**2))), float(np.mean(err)), arw, allan, len(dev)


def accuracy_table(spec, seeds: int) -> list[str]:
    lines = ["## Maytagging accuracy (40 pairs x 60 s, cvg_two_axis, 40.8°)", "",
             "| noise | seeds | pairs | per-pair std [mrad] | theory [mrad] | ratio | mean error [mrad] "
             "| RMS error [mrad] |",
             "|---|---|---|---|---|---|---|---|"]
    white = [run(maytagging, white_only(spec), 1000 + s) for s in range(seeds)]
    std, rms, mean, arw, _, n = pooled(white)
    lines.append(f"| white only | {seeds} | {n} | {std * 1e3:.2f} | {arw * 1e3:.2f} (ARW) | {std / arw:.3f} | "
                 f"{mean * 1e3:+.2f} | {rms * 1e3:.2f} |")
    seqs = [run(maytagging, spec, 2000 + s, start_offset_deg=off) for s, off in enumerate([0, 0, 0, 0, 90, 90, 90])]
    std, rms, mean, _, allan, n = pooled(seqs)
    lines.append(f"| grade (BI + RRW) | 7 | {n} | {std * 1e3:.2f} | {allan * 1e3:.2f} (Allan) | {std / allan:.3f} | "
                 f"{mean * 1e3:+.2f} | {rms * 1e3:.2f} |")
    lines += ["", "### Thesis table 4.3 analogue (sequences 1-4 at home, 5-7 at 90°)", "",
              "| sequence | mean [°] | std [mrad] | error [mrad] | distance from group mean [mrad] |",
              "|---|---|---|---|---|"]
    for group, idx in (("1-4", range(0, 4)), ("5-7", range(4, 7))):
        grp = [seqs[i] for i in idx]
        rows = nfm.sequence_table(grp, [str(i + 1) for i in idx])
        for r, row in zip(grp, rows):
            lines.append(f"| {row['sequence']} | {row['mean_deg'] % 360:.3f} | {row['std_mrad']:.2f} | "
                         f"{r.azimuth_error * 1e3:+.2f} | {row['distance_mrad']:+.2f} |")
        rep = max(abs(row["distance_mrad"]) for row in rows)
        lines.append(f"| repeatability {group} | | | | **{rep:.2f}** (thesis {'2.4' if group == '1-4' else '0.75'}) |")
    return lines


def dwell_table(spec, seeds: int, dwells) -> list[str]:
    lines = ["", f"## Dwell time and ordering at equal total time ({TOTAL_S / 60:.0f} min, cvg_two_axis grade)", "",
             "| dwell [s] | ordering | pairs | per-pair std [mrad] | Allan theory [mrad] | RMS mean error [mrad] | "
             "theory/sqrt(pairs) [mrad] |", "|---|---|---|---|---|---|---|"]
    for dwell in dwells:
        count = int(TOTAL_S / (2 * dwell))
        for ordering in ("ABAB", "ABBA"):
            c = count - count % 2 if ordering == "ABBA" else count
            res = [run(maytagging, spec, 3000 + s, dwell_s=dwell, count=c, ordering=ordering) for s in range(seeds)]
            std, rms, _, _, allan, _ = pooled(res)
            lines.append(f"| {dwell:g} | {ordering} | {c} | {std * 1e3:.2f} | {allan * 1e3:.2f} | {rms * 1e3:.2f} | "
                         f"{allan / np.sqrt(c) * 1e3:.2f} |")
    return lines


def carousel_table(spec, seeds: int, laps_list) -> list[str]:
    lines = ["", "## Carousel at 10 °/s: error vs laps (cvg_two_axis grade)", "",
             "| laps | RMS error [mrad] | ARW theory [mrad] | Allan-equivalent theory [mrad] |", "|---|---|---|---|"]
    lat = np.radians(40.8)
    for laps in laps_list:
        res = [run(carousel, spec, 4000 + s, laps=laps) for s in range(seeds)]
        err = np.sqrt(np.mean([r.azimuth_error ** 2 for r in res]))
        arw = th.harmonic_sigma(spec.specs["gyro"].noise.white[:2], 1, lat) / np.sqrt(laps * 36.0)
        allan = res[0].theory["allan_unit_sigma"] / np.sqrt(laps)
        lines.append(f"| {laps} | {err * 1e3:.2f} | {arw * 1e3:.2f} | {allan * 1e3:.2f} |")
    return lines


def redundant_table(spec, sessions: int) -> list[str]:
    res = [run(redundant, spec, 5000 + s) for s in range(sessions)]
    lines = ["", f"## Redundant configuration ({sessions} sessions x 10 turns; thesis table 4.4)", "",
             "| pairing | repeatability [mrad] | [°] | std over turns [mrad] | noise model, bias wander included "
             "[mrad] |", "|---|---|---|---|---|"]
    expected = np.sqrt(np.mean([r.theory["pairing_spread"].turn_std ** 2 for r in res], axis=0))
    for row, model in zip(nfm.pairing_table(res), expected):
        lines.append(f"| {row['pairing_deg']}° | {row['repeatability_mrad']:.2f} | {row['repeatability_deg']:.3f} | "
                     f"{row['std_over_turns_mrad']:.2f} | {model * 1e3:.2f} |")
    lines.append(f"| (Allan theory per estimate, bias known) | | | {res[0].theory['allan_unit_sigma'] * 1e3:.2f} | |")
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    spec = load_spec("cvg_two_axis")
    t0 = time.time()
    seeds = 3 if args.quick else args.seeds
    lines = accuracy_table(spec, seeds)
    lines += dwell_table(spec, 2 if args.quick else max(3, seeds // 2), (30.0, 60.0, 120.0) if args.quick
                         else (15.0, 30.0, 60.0, 120.0, 240.0))
    lines += carousel_table(spec, 3 if args.quick else seeds, (2, 8) if args.quick else (2, 4, 8, 16))
    lines += redundant_table(spec, 5)
    lines += ["", f"_{time.time() - t0:.0f} s_"]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out is not None:
        args.out.write_text(text)


if __name__ == "__main__":
    main()
