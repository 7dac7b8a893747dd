"""Land INS heading consistency after paper 001's pre-calibration: error / sigma over simulated units.

Each unit of the tactical grade of table 3-1 (``draw_unit(spec, 1000 + k)``) drives the pre-calibration
profile (``workbench.sim.roads.precalibration_legs``: 300 s rest, four 90° turns with a 120 s stop after
each); the land INS (20 states) filters the raw samples, told the grade (``grade_errors``) with the bias
instability as one Gauss-Markov state (``gauss_markov``, before) or as the three-rung Gauss-Markov ladder
(``ladder``, the default; :mod:`workbench.nav.bias_model`), or as a random walk ``B² / 3600 s``
(``random_walk``). The heading error at the end of the last stop is compared with the filter's heading
sigma. Unit cases: ``white`` (white noise only, no bias), ``bias`` (the unit's turn-on biases and white
noise), ``flicker`` (the turn-on biases, white noise and the grade's bias instability B, nothing else),
one error of the unit beside the turn-on biases and white noise (``scale``: the scale factors,
``misalignment``: the off-diagonal of M, ``nonlinearity``, ``g_sensitivity``, ``rrw``: the rate random
walk), ``all`` (every error of the grade). A consistent filter gives rms(error / sigma) ~ 1 (chi-square
95 % band printed) and a median |error / sigma| of 0.674. The same units (seeds) in every column.

``--turn-coherence-deg 90``: the filter takes the gyro's scale factor and misalignment in the turns as
attitude noise coherent over 90° (``LandInsConfig.turn_coherence_rad``).

    python benchmarks/land_ins_consistency.py [--units 40] [--cases white,flicker,all] [--turn-coherence-deg 90]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.stats import chi2

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

LAT_DEG, LON_DEG, H_M = 40.0, 33.0, 900.0


def unit_for(case: str, k: int):
    """Unit ``k`` of the tactical grade with the errors of ``case`` (module docstring)."""
    from workbench.grade_types import NoiseSpec
    from workbench.grades import draw_unit, load_spec
    from workbench.model import TriadModel

    unit = draw_unit(load_spec("tactical_low_noise"), 1000 + k)
    if case == "all":
        return unit
    changes = {}
    for t in ("gyro", "accel"):
        n, m = unit.noise_of(t), getattr(unit, t)
        sm = m.scale_misalignment
        kept = {"scale": {"scale_misalignment": np.diag(np.diag(sm))},
                "misalignment": {"scale_misalignment": sm - np.diag(np.diag(sm))},
                "nonlinearity": {"nonlinearity": m.nonlinearity},
                "g_sensitivity": {"g_sensitivity": m.g_sensitivity}}.get(case, {})
        bias = m.bias if case != "white" else np.zeros(3)
        changes[t] = TriadModel(bias=bias, **kept)
        changes[f"{t}_noise"] = NoiseSpec(white=n.white, bias_instability=n.bias_instability if case == "flicker"
                                          else np.zeros(3), rrw=n.rrw if case == "rrw" else np.zeros(3))
    return replace(unit, **changes)


def heading_z(case: str, k: int, bias_models: tuple[str, ...],
              turn_coherence_rad: float | None = None) -> dict[str, tuple[float, float]]:
    """(heading error rad, heading sigma rad) at the end of the pre-calibration, per bias model; the filter's
    ``turn_coherence_rad`` (``LandInsConfig``)."""
    from workbench.grades import load_spec
    from workbench.nav.compensate import imu_samples
    from workbench.nav.land_ins import LandInsConfig, grade_errors, run_land_ins
    from workbench.session import Site
    from workbench.sim.roads import precalibration_legs
    from workbench.sim.vehicle import drive, drive_config

    site = Site(LAT_DEG, LON_DEG, H_M)
    session, truth = drive(drive_config(precalibration_legs(), site, 0.0), unit_for(case, k), 1000 + k)
    tr = truth["trajectory"]
    samples = imu_samples(session.samples, session.sample_rate_hz)
    out = {}
    for bm in bias_models:
        res = run_land_ins(samples, site.latitude, np.radians(LON_DEG), H_M, 0.0,
                           grade_errors(load_spec("tactical_low_noise"), bias_model=bm),
                           LandInsConfig(turn_coherence_rad=turn_coherence_rad))
        i = min(int(np.searchsorted(tr["t"].to_numpy(), res.t[-1])), len(tr) - 1)
        err = (res.rph[-1, 2] - tr["yaw"].iloc[i] + np.pi) % (2 * np.pi) - np.pi
        out[bm] = (float(err), float(res.sigma[-1, 8]))
    return out


def main() -> None:
    """Command-line entry: print the table."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--units", type=int, default=40)
    p.add_argument("--cases", default="white,flicker,all")
    p.add_argument("--bias-models", default="gauss_markov,ladder")
    p.add_argument("--turn-coherence-deg", type=float, default=None,
                   help="the gyro scale factor and misalignment as turn noise coherent over this angle")
    a = p.parse_args()
    models = tuple(a.bias_models.split(","))
    lo, hi = np.sqrt(chi2.ppf([0.025, 0.975], a.units) / a.units)
    print(f"heading at the end of the pre-calibration, tactical grade, {a.units} units; rms(error / sigma) "
          f"chi-square 95 % band [{lo:.2f}, {hi:.2f}], median |error / sigma| 0.674 if consistent")
    print(f"{'case':8s} {'bias model':13s} {'sigma °':>8s} {'rms err °':>9s} {'rms e/s':>8s} {'median':>7s}")
    t0, c0 = time.perf_counter(), time.process_time()
    for case in a.cases.split(","):
        turn = None if a.turn_coherence_deg is None else np.radians(a.turn_coherence_deg)
        rows = [heading_z(case, k, models, turn) for k in range(a.units)]
        for bm in models:
            e, s = np.array([r[bm] for r in rows]).T
            z = e / s
            print(f"{case:8s} {bm:13s} {np.degrees(s).mean():8.3f} {np.degrees(np.sqrt(np.mean(e ** 2))):9.3f} "
                  f"{np.sqrt(np.mean(z ** 2)):8.2f} {np.median(np.abs(z)):7.2f}", flush=True)
    print(f"{time.process_time() - c0:.0f} s CPU, {time.perf_counter() - t0:.0f} s wall")


if __name__ == "__main__":
    main()
