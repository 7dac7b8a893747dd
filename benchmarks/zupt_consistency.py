"""ZUPT / ZARUPT alignment: normalised errors over seeds and paper 001's heading figures (Fig. 4-1, 5-4, 5-5).

Closed-form synthetic table data (``tests/nav/synthetic.py``), HG1700 noise of paper 001 table 5-1
(ARW 0.125 °/√h, VRW 0.065 m/s/√h), true biases drawn from the filter's priors (3 °/h, 1 mg), see
:func:`tests.nav.test_zupt.normalised_errors`. Prints, per case (static with the heading held, or with
none (gyrocompass); rotating with four 90° turns and no external heading, or an external heading of
1-sigma 17°, 30°, 90°, 180° drawn from it; ZUPT / ZUPT + ZARUPT), the rms of error / sigma of roll, pitch, heading, accel and gyro
bias over the seeds with the chi-square 95 % band and the CPU time of each case's runs, then the
final heading sigma and rms heading error of the rotating gyrocompass case beside the closed-form limit
``ARW / (Omega cos(lat) sqrt(T))`` (T the whole record: the heading is the east gyro rate over the horizontal
Earth rate, the turns only separate the bias) and beside the paper's figures. The ZARUPT measures the vertical
rate too; ZUPT alone does not, so its heading turns at the unknown vertical gyro bias ``b_D`` and it has to
estimate the drift from the heading's history: its limit is the end value of ``psi(t) = psi_T + b_D (t - T)``
observed through ``Omega cos(lat) psi(t)`` with white noise ARW over T, the prior of ``b_D`` and the levelling
window's gyro mean (:func:`tests.nav.test_zupt.zupt_limit`).

    python benchmarks/zupt_consistency.py [--seeds 20] [--hold 60] [--paper-hold 240]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.stats import chi2

from tests.nav.synthetic import LAT
from tests.nav.test_zupt import GYRO_PRIOR, HG_ARW, TURN_S, normalised_errors, zupt_limit
from workbench.earth import EARTH_RATE

LABELS = ("roll", "pitch", "heading", "ba_x", "ba_y", "ba_z", "bg_x", "bg_y", "bg_z")


def main() -> None:
    """Command-line entry: print the consistency table and the heading figures."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument("--hold", type=float, default=60.0, help="hold of the consistency runs, s")
    p.add_argument("--paper-hold", type=float, default=240.0, help="hold of the paper-figure runs, s (20 min)")
    a = p.parse_args()
    t0 = time.process_time()
    lo, hi = np.sqrt(chi2.ppf([0.025, 0.975], a.seeds) / a.seeds)
    print(f"rms(error / sigma) over {a.seeds} seeds, {a.hold:g} s holds; chi-square 95 % band [{lo:.2f}, {hi:.2f}]")
    print(f"{'case':30s} " + " ".join(f"{x:>7s}" for x in LABELS) + "   CPU s")
    cases = [("static", "held"), ("static", None)] + [("rotating", s) for s in (None, 17.0, 30.0, 90.0, 180.0)]
    for profile, heading in cases:
        for zarupt in (False, True):
            c0 = time.process_time()
            at_rest = profile == "static" and heading is None
            z, _, _ = normalised_errors(profile, zarupt, range(a.seeds), a.hold,
                                        heading_sigma_deg=None if heading == "held" else heading,
                                        gyrocompass_at_rest=at_rest)
            rms = np.sqrt(np.mean(z ** 2, axis=0))
            given = (" heading held" if heading == "held" else " no heading" if heading is None
                     else f" heading {heading:g}°")
            print(f"{profile + given + (' ZARUPT' if zarupt else ' ZUPT'):30s} " + " ".join(f"{x:7.2f}" for x in rms)
                  + f"  {time.process_time() - c0:6.1f}")
    total = a.paper_hold + 4 * (a.paper_hold + TURN_S)
    limit = np.degrees(HG_ARW / (EARTH_RATE * np.cos(LAT) * np.sqrt(total)))
    limits = {True: limit, False: np.degrees(zupt_limit(HG_ARW, total, GYRO_PRIOR, 30.0))}
    print(f"\nrotating, gyrocompass, {total / 60:.0f} min ({a.paper_hold:g} s holds, four 90° turns), {a.seeds} seeds; "
          f"closed-form limit {limit:.2f}° (ZUPT alone, vertical gyro bias from its prior and the 30 s levelling window: "
          f"{limits[False]:.2f}°)")
    print(f"{'':8s} {'mean sigma':>10s} {'vs limit':>8s} {'rms error':>10s} {'rms e/sig':>9s}  paper 001")
    paper = {False: "~3° (Fig. 5-5, HG1700); ZARUPT better than ZUPT at low noise (Fig. 4-1)",
             True: "< 1° (Fig. 5-5, HG1700), ~0.6° rms over 6 lab runs (Fig. 5-4)"}
    for zarupt in (False, True):
        z, err, sig = normalised_errors("rotating", zarupt, range(a.seeds), a.paper_hold)
        print(f"{'ZARUPT' if zarupt else 'ZUPT':8s} {sig.mean():9.2f}° {sig.mean() / limits[zarupt] - 1:+8.1%} "
              f"{np.sqrt(np.mean(err ** 2)):9.2f}° {np.sqrt(np.mean(z[:, 2] ** 2)):9.2f}  {paper[zarupt]}")
    print(f"{time.process_time() - t0:.0f} s CPU")


if __name__ == "__main__":
    main()
