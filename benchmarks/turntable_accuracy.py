"""Accuracy sweep of the turntable calibration over seeds and grades (slow; not a test).

For each grade and seed: the ``multiposition`` procedure (``--positions``, ``--dwell`` s per
position) and the ``rate`` procedure on the simulated rig, compared with the unit's truth at
the session temperature. Writes a Markdown table (``--out``, default
benchmarks/results/turntable_accuracy.md) and prints it:

- accel: max |bias error| (mg), max |SF error| (ppm), max |misalignment error| (mrad),
  max residual after compensation (mg), worst |error| / sigma;
- gyro static: max |bias error| (°/h), worst |error| / sigma;
- gyro rate: max |SF error| (ppm), max |misalignment error| (mrad), max residual (% FS),
  worst |error| / sigma.

Each cell is the worst over the axes, then the median and the worst over the seeds
("median / worst"); the share of all coefficient estimates within 4 sigma is the last column.

Then the honesty of the sigmas (``--sigma-seeds`` seeds of ``--sigma-grade``, default 12 of
industrial_mems): for 6 and 24 positions at 60 s and 5 s dwell, the z-scores
``(estimate - truth) / sigma`` of the accelerometer bias, scale factor and misalignment and
of the gyro bias, pooled over axes and seeds: their rms (1 for an honest sigma) and max
(for k Gaussian z-scores, |z| exceeds 3.3 with ~5 % probability at k = 36 and 3.4 at
k = 72), without and with the unit's bias instability given to the analysis (the grade's
value, as from an Allan test); "warned" counts the fits that say their dwells could hide a
bias instability larger than the bias sigma.

Usage: python benchmarks/turntable_accuracy.py [--seeds 5] [--grades industrial_mems,...] [--sigma-seeds 12]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import procedures.multiposition as multiposition
import procedures.rate as rate
from workbench import units
from workbench.errors import WorkbenchError
from workbench.grades import grade_names, load_spec
from workbench.jobs import simulate

MG = 9.80665e-3
DEG_H = np.radians(1.0) / 3600.0
OFF = ~np.eye(3, dtype=bool)


def _effective(model, temperature_c):
    t = np.array([temperature_c])
    if model.thermal is None:
        return model.bias, model.scale_misalignment
    return (model.bias + model.thermal.bias_shift(t)[0],
            model.scale_misalignment + np.diag(model.thermal.scale_shift(t)[0]))


def _z(err, sigma):
    z = np.abs(err) / sigma
    return z[np.isfinite(z)]


def run_one(grade: str, seed: int, positions: int, dwell: float) -> dict:
    """Errors of one unit (grade, seed): a dict of scalars (NaN where not applicable)."""
    spec = load_spec(grade)
    out: dict = {}
    zs = []
    session, truth = simulate(multiposition.sequence(spec, positions=positions, dwell_s=dwell), spec, seed=seed)
    res = multiposition.analyze(session)
    temp = float(session.samples["temp"].mean()) if "temp" in session.samples else 23.0
    acc = res.payload["accel"]
    b, m = _effective(truth.accel, temp)
    out["acc_bias_mg"] = np.abs(acc.bias - b).max() / MG
    out["acc_sf_ppm"] = np.abs(np.diag(acc.scale_misalignment - m)).max() * 1e6
    out["acc_mis_mrad"] = np.abs((acc.scale_misalignment - m)[OFF]).max() * 1e3
    out["acc_res_mg"] = np.abs(acc.residuals[["after_x", "after_y", "after_z"]].to_numpy()).max() / MG
    za = np.concatenate([_z(acc.bias - b, acc.bias_sigma),
                         _z(acc.scale_misalignment - m, acc.scale_misalignment_sigma).ravel()])
    out["acc_z"] = za.max()
    gs = res.payload["gyro"]
    gb, gm = _effective(truth.gyro, temp)
    out["gyro_bias_deg_h"] = np.abs(gs.bias - gb).max() / DEG_H
    zg = _z(gs.bias - gb, gs.bias_sigma)
    out["gyro_bias_z"] = zg.max()
    zs += [za, zg]
    session, truth = simulate(rate.sequence(spec), spec, seed=seed + 10_000)
    res = rate.analyze(session)
    gr, fs = res.payload["gyro"], res.payload["full_scale"]
    _, gm = _effective(truth.gyro, float(session.samples["temp"].mean()) if "temp" in session.samples else 23.0)
    out["gyro_sf_ppm"] = np.abs(np.diag(gr.scale_misalignment - gm)).max() * 1e6
    out["gyro_mis_mrad"] = np.abs((gr.scale_misalignment - gm)[OFF]).max() * 1e3
    out["gyro_res_pct_fs"] = np.abs(gr.residuals[["after_x", "after_y", "after_z"]].to_numpy()).max() / fs * 100
    zr = _z(gr.scale_misalignment - gm, gr.scale_misalignment_sigma).ravel()
    out["gyro_rate_z"] = zr.max()
    zs.append(zr)
    allz = np.concatenate(zs)
    out["within_4sigma"] = float(np.mean(allz < 4))
    return out


SIGMA_CASES = [(6, 60.0), (6, 5.0), (24, 60.0), (24, 5.0)]  # (positions, dwell s)


def sigma_z(grade: str, seed: int, positions: int, dwell: float) -> dict[bool, dict]:
    """Signed z-scores of one simulated multiposition session, analysed without (False) and with
    (True) the grade's bias instability: {given: {quantity: array, "warned": count}}."""
    spec = load_spec(grade)
    session, truth = simulate(multiposition.sequence(spec, positions=positions, dwell_s=dwell), spec, seed=seed)
    temp = float(session.samples["temp"].mean()) if "temp" in session.samples else 23.0
    b, m = _effective(truth.accel, temp)
    gb, _ = _effective(truth.gyro, temp)
    prior = {"accel_bias_instability_mg": (spec.accel.noise.bias_instability / units.factor("mg")).tolist(),
             "gyro_bias_instability_deg_h": (spec.gyro.noise.bias_instability / units.factor("deg/h")).tolist()}
    out = {}
    for given in (False, True):
        res = multiposition.analyze(session, **(prior if given else {}))
        acc, gyr = res.payload["accel"], res.payload["gyro"]
        dm = acc.scale_misalignment - m
        out[given] = {"acc bias": (acc.bias - b) / acc.bias_sigma,
                      "acc SF": np.diag(dm) / np.diag(acc.scale_misalignment_sigma),
                      "acc mis": dm[OFF] / acc.scale_misalignment_sigma[OFF],
                      "gyro bias": (gyr.bias - gb) / gyr.bias_sigma,
                      "warned": sum("would not show" in w for w in res.warnings)}
    return out


def sigma_table(grade: str, seeds: int) -> list[str]:
    """Markdown table of z-score rms / max per quantity, position set, dwell and prior."""
    quantities = ["acc bias", "acc SF", "acc mis", "gyro bias"]
    lines = [f"Sigma honesty, {grade}, {seeds} seeds (seed 100...): z = (estimate - truth) / sigma pooled over "
             "axes and seeds, cells = rms / max |z|; \"B given\" = the unit's bias instability passed to the "
             "analysis; warned = fits (of 2 per seed) warning that their dwells could hide a bias instability.", "",
             "| positions x dwell | B given | " + " | ".join(quantities) + " | warned |",
             "|---" * (len(quantities) + 3) + "|"]
    for positions, dwell in SIGMA_CASES:
        runs = [sigma_z(grade, 100 + s, positions, dwell) for s in range(seeds)]
        for given in (False, True):
            cells = []
            for q in quantities:
                z = np.concatenate([r[given][q] for r in runs])
                cells.append(f"{np.sqrt(np.mean(z**2)):.2f} / {np.abs(z).max():.2f}")
            warned = sum(r[given]["warned"] for r in runs)
            lines.append(f"| {positions} x {dwell:g} s | {'yes' if given else 'no'} | " + " | ".join(cells)
                         + f" | {warned} |")
            print(lines[-1], flush=True)
    return lines


COLUMNS = [("acc_bias_mg", "acc bias [mg]"), ("acc_sf_ppm", "acc SF [ppm]"), ("acc_mis_mrad", "acc mis [mrad]"),
           ("acc_res_mg", "acc res [mg]"), ("acc_z", "acc err/σ"), ("gyro_bias_deg_h", "gyro bias [°/h]"),
           ("gyro_bias_z", "bias err/σ"), ("gyro_sf_ppm", "gyro SF [ppm]"), ("gyro_mis_mrad", "gyro mis [mrad]"),
           ("gyro_res_pct_fs", "gyro res [% FS]"), ("gyro_rate_z", "rate err/σ"), ("within_4sigma", "share < 4σ")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--grades", default=",".join(grade_names()))
    ap.add_argument("--positions", type=int, default=24)
    ap.add_argument("--dwell", type=float, default=60.0)
    ap.add_argument("--sigma-seeds", type=int, default=12, help="seeds of the sigma-honesty sweep (0: skip)")
    ap.add_argument("--sigma-grade", default="industrial_mems")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "turntable_accuracy.md"))
    a = ap.parse_args()
    lines = [f"Turntable accuracy: {a.positions} positions x {a.dwell:g} s + rate procedure defaults, "
             f"{a.seeds} seeds per grade; cells = median / worst over seeds of the worst axis.", "",
             "| grade | " + " | ".join(c[1] for c in COLUMNS) + " |", "|---" * (len(COLUMNS) + 1) + "|"]
    for grade in a.grades.split(","):
        rows = []
        try:
            rows = [run_one(grade, 100 + s, a.positions, a.dwell) for s in range(a.seeds)]
        except WorkbenchError as exc:
            lines.append(f"| {grade} | error: {exc} |")
            print(lines[-1], flush=True)
            continue
        cells = []
        for key, _ in COLUMNS:
            v = np.array([r[key] for r in rows], float)
            cells.append(f"{np.median(v):.3g}" if key == "within_4sigma" else f"{np.median(v):.3g} / {v.max():.3g}")
        lines.append(f"| {grade} | " + " | ".join(cells) + " |")
        print(lines[-1], flush=True)
    if a.sigma_seeds > 0:
        lines += [""] + sigma_table(a.sigma_grade, a.sigma_seeds)
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
