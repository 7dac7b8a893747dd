"""Ferraris calibration: this workbench and imucal on the same simulated sessions, against the truth.

For each grade and seed the simulated rig records one Ferraris session (six 10-s positions and
three -360° turns at ``--turn-rate`` °/s, site latitude 40.8°); ``procedures.ferraris`` (its
defaults, and with the grade's nonlinearity given) and imucal's ``FerrarisCalibration`` (the
paper's equations; ``grav`` = the site's normal gravity, ``expected_angle`` = -360°, gyro in
°/s) both calibrate it. Errors against the unit's truth at the session temperature, per
coefficient, pooled over axes and seeds (rms / worst):

- accelerometer bias (mg), scale factor (ppm), misalignment (mrad);
- gyro bias (°/h), scale factor (ppm), misalignment (mrad).

imucal's convention (shared/data/imucal_ferraris/README.md): ``raw = K R x + b`` (gyro also
``+ K_ga acc``), so ``K R`` is our ``I + M``. For ours, the z rms column is the rms of
``error / sigma`` (1 for an honest sigma); imucal gives no uncertainty.

Usage: python benchmarks/ferraris_vs_imucal.py [--seeds 5] [--grades a,b,...] [--turn-rate 90]
(imucal: ``pip install imucal``; the benchmark says so and stops if it is missing).
"""

from __future__ import annotations

import argparse
import sys
import warnings

import numpy as np

import procedures.ferraris as ferraris
from workbench import units
from workbench.grades import load_spec
from workbench.jobs import simulate

GRADES = ("industrial_mems", "quasi_tactical", "tactical_low_noise", "navigation_grade")
LABELS = {"x_p": "x-up", "x_a": "x-down", "y_p": "y-up", "y_a": "y-down", "z_p": "z-up", "z_a": "z-down"}
OFF = ~np.eye(3, dtype=bool)
ROWS = (("accel bias", "mg"), ("accel SF", "ppm"), ("accel mis", "mrad"),
        ("gyro bias", "deg/h"), ("gyro SF", "ppm"), ("gyro mis", "mrad"))


def imucal_fit(session) -> dict[str, np.ndarray]:
    """imucal's Ferraris result on ``session``: accel/gyro bias (SI) and I + M = K R."""
    from imucal import FerrarisCalibration, FerrarisSignalRegions

    by_label = {s.label: s.index for s in session.steps}
    regions = {}
    for key, label in LABELS.items():
        regions[f"acc_{key}"] = session.accel(by_label[label])
        regions[f"gyr_{key}"] = np.degrees(session.gyro(by_label[label]))
    for axis in "xyz":
        regions[f"acc_{axis}_rot"] = session.accel(by_label[f"{axis}_rot"])
        regions[f"gyr_{axis}_rot"] = np.degrees(session.gyro(by_label[f"{axis}_rot"]))
    cal = FerrarisCalibration(grav=session.site.gravity, expected_angle=-360.0).compute(
        FerrarisSignalRegions(**regions), session.sample_rate_hz, "m/s^2", "deg/s")
    return {"accel_bias": np.asarray(cal.b_a), "accel_gain": np.asarray(cal.K_a) @ np.asarray(cal.R_a),
            "gyro_bias": np.radians(np.asarray(cal.b_g)), "gyro_gain": np.asarray(cal.K_g) @ np.asarray(cal.R_g)}


def _truth(model, temperature_c: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.array([temperature_c])
    return (model.bias + model.thermal.bias_shift(t)[0],
            np.eye(3) + model.scale_misalignment + np.diag(model.thermal.scale_shift(t)[0]))


def _errors(fit: dict, truth) -> dict[str, np.ndarray]:
    """Per-coefficient errors (SI) of a fit given as biases and gains."""
    out = {}
    for triad in ("accel", "gyro"):
        b, gain = _truth(getattr(truth[0], triad), truth[1])
        d = fit[f"{triad}_gain"] - gain
        out[f"{triad} bias"] = fit[f"{triad}_bias"] - b
        out[f"{triad} SF"] = np.diag(d)
        out[f"{triad} mis"] = d[OFF]
    return out


def _ours(result) -> tuple[dict, dict]:
    p = result.payload
    fit, sigma = {}, {}
    for triad in ("accel", "gyro"):
        f = p[triad]
        fit[f"{triad}_bias"], fit[f"{triad}_gain"] = f.bias, np.eye(3) + f.scale_misalignment
        sigma[f"{triad} bias"] = f.bias_sigma
        sigma[f"{triad} SF"] = np.diag(f.scale_misalignment_sigma)
        sigma[f"{triad} mis"] = f.scale_misalignment_sigma[OFF]
    return fit, sigma


def run(grade: str, seeds: int, turn_rate: float) -> None:
    """Print the comparison table of one grade."""
    spec = load_spec(grade)
    nonlin = float(spec.gyro.nonlinearity[0] / units.factor("ppm/(deg/s)"))
    err: dict[str, dict[str, list]] = {k: {r: [] for r, _ in ROWS} for k in ("ours", "ours+nl", "imucal")}
    z: dict[str, list] = {r: [] for r, _ in ROWS}
    for seed in range(1, seeds + 1):
        session, truth = simulate(ferraris.sequence(spec, dwell_s=10.0, turn_rate_dps=turn_rate), spec, seed=seed)
        temp = float(session.samples["temp"].mean())
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            theirs = imucal_fit(session)
        for name, opts in (("ours", {}), ("ours+nl", {"gyro_nonlinearity_ppm_per_dps": nonlin})):
            fit, sigma = _ours(ferraris.analyze(session, **opts))
            for r, e in _errors(fit, (truth, temp)).items():
                err[name][r].append(e)
                if name == "ours+nl":
                    z[r].append(e / sigma[r])
        for r, e in _errors(theirs, (truth, temp)).items():
            err["imucal"][r].append(e)
    print(f"\n{grade}: {seeds} seeds, turns of {360 / turn_rate:.0f} s; error rms / worst against the truth")
    print(f"{'coefficient':<12} {'unit':>6} {'workbench':>19} {'workbench+nonlin':>19} {'imucal':>19} {'z rms':>6}")
    for r, unit in ROWS:
        cells = []
        for name in ("ours", "ours+nl", "imucal"):
            e = np.concatenate(err[name][r]) / units.factor(unit)
            cells.append(f"{np.sqrt(np.mean(e**2)):>9.3g} / {np.abs(e).max():<7.3g}")
        zz = np.concatenate(z[r])
        print(f"{r:<12} {units.label(unit):>6} {cells[0]:>19} {cells[1]:>19} "
              f"{cells[2]:>19} {np.sqrt(np.mean(zz**2)):>6.2f}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--grades", default=",".join(GRADES))
    ap.add_argument("--turn-rate", type=float, default=90.0, help="°/s (90: 4-s turns)")
    args = ap.parse_args()
    try:
        import imucal  # noqa: F401
    except ImportError:
        print("imucal is not installed: pip install imucal", file=sys.stderr)
        return 2
    for grade in args.grades.split(","):
        run(grade, args.seeds, args.turn_rate)
    return 0


if __name__ == "__main__":
    sys.exit(main())
