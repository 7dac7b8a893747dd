"""Seed tables of the land-navigation validations, seed beside measured.

* thesis (shared/seeds/000_...) tables 2.8 and 2.9 and Fig. 2.18: the AXD-LNS on a thesis-like
  simulated drive (``workbench.sim.roads.thesis_drive``, quasi-tactical unit, odometer +4 % after
  the stop at 3000 s, GPS lost at 3600 s, ~29 km in 45 min without GPS), through the
  ``lns-dead-reckoning`` procedure (statistics against the GPS kept as reference, as the thesis);
* paper 001 (shared/seeds/001_...) table 4-1 and the eq. 49 fit (table 4-2): the covariance
  analysis of :func:`workbench.nav.land_ins.covariance_analysis` for 8 constant heading rates
  (chosen here, the paper does not give them: 0, 0.0125, 0.025, 0.125, 0.3, 0.45, 0.6 and 1 °/s,
  i.e. 0-3600° of heading change in the hour) x the two grades of table 3-1, each after the
  pre-calibration profile, 1 h at 20 m/s; CEP after the hour and the fit of eq. 49; twice: with
  table 3-1's bias a turn-on constant (our grade fixtures) and with it also an in-run bias drawn
  anew over ``--in-run-bias-h`` hours (paper 001's bias instability noise of eq. 4-5, whose value
  the paper does not give), each with the error budget of the straight case;
* ``--filter-speed``: CPU time of one 1-h 100 Hz land-INS filter run (the target is 30 s on one core);
* ``--monte-carlo RUNS [--scheduler local|tcp://HOST:PORT] [--cruise-s S]``: the sampled Monte Carlo
  of table 4-1 on Dask with a progress bar, resumable (``--mc-dir``).

Usage: ``python benchmarks/seed_tables.py [--skip-lns] [--filter-speed] [--monte-carlo RUNS] [--out FILE.json]``.
The calibrated runs use the nav tests' lab-calibration errors (tests/nav/conftest.py: gyro bias
1 °/h, accel bias 0.05 mg, scale / misalignment 100 ppm / 0.1 mrad).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "nav"))

RATES_DPS = (0.0, 0.0125, 0.025, 0.125, 0.3, 0.45, 0.6, 1.0)
SEED_4_1 = {"tactical_low_noise": (29720, 25864, 25453, 7845, 1339, 257, 96, 43),
            "navigation_grade": (1478, 1078, 1062, 534, 144, 39, 16, 10)}
SEED_4_2 = {"tactical_low_noise": (43.0, 29677.0, -0.003), "navigation_grade": (10.0, 1468.0, -0.003)}
SEED_2_8 = {"max": 5.5, "mean": 4.0, "std": 0.9, "rms": 4.2, "one_sigma": 4.9}
SEED_2_9 = {"max": 1.3, "mean": 0.6, "std": 0.3, "rms": 0.7, "one_sigma": 0.9}


def lns_tables(seed: int = 1) -> dict:
    """Thesis tables 2.8 / 2.9 and Fig. 2.18 on the simulated drive."""
    from conftest import calibration_from_truth
    from procedures import lns_dead_reckoning as proc
    from workbench.grades import draw_unit, load_spec

    unit = draw_unit(load_spec("quasi_tactical"), seed)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        session = proc.record_drive(unit, seed, Path(tmp) / "session")
        t_sim = time.perf_counter() - t0
        t0 = time.process_time()
        res = proc.analyze(session, calibration_from_truth(unit))
        t_cpu = time.process_time() - t0
    r = res.result
    print(f"\nthesis-like drive: {r['calibrated']['sf_state']['distance_m'] / 1000:.1f} km without GPS "
          f"(simulated in {t_sim:.0f} s wall; 6 filter runs {t_cpu:.1f} s CPU)")
    for title, seed_tab, variant in (("table 2.8 (no SF state)", SEED_2_8, "no_sf_state"),
                                     ("table 2.9 (SF state)", SEED_2_9, "sf_state")):
        print(f"{title:26s} " + "  ".join(f"{k:>9s}" for k in seed_tab))
        print(f"{'  seed (thesis) %':26s} " + "  ".join(f"{v:9.2f}" for v in seed_tab.values()))
        for mode in ("raw", "calibrated", "wrong_bias"):
            e = r[mode][variant]["error_pct"]
            print(f"{'  measured ' + mode + ' %':26s} " + "  ".join(f"{e[k]:9.2f}" for k in seed_tab))
    sf = r["calibrated"]["sf_state"]
    print(f"Fig. 2.18 SF estimate: seed ~3.5 % within seconds; measured {100 * sf['odo_scale_at_loss']:.2f} % "
          f"(1-sigma {100 * sf['odo_scale_sigma_at_loss']:.2f} %), within 0.5 % of it {sf['sf_settle_s']:.0f} s "
          "after the restart (true +4 %)")
    return r


def eq49_fit(ceps: dict[str, list[float]], label: str) -> dict:
    """The eq. 49 fit ``dp = a0 + a1 exp(a2 Δψ)`` of CEPs per grade over :data:`RATES_DPS`, printed beside table 4-2."""
    from scipy.optimize import curve_fit

    def model(x, a0, a1, a2):
        return a0 + a1 * np.exp(a2 * x)

    dpsi = 3600.0 * np.asarray(RATES_DPS)
    fits = {}
    print(f"eq. 49 fit dp = a0 + a1 exp(a2 Δψ) ({label}):")
    for grade, values in ceps.items():
        try:
            p, _ = curve_fit(model, dpsi, values, p0=(values[-1], values[0], -0.003), maxfev=20000)
        except RuntimeError:
            print(f"  {grade:20s} no fit")
            continue
        fits[grade] = p.tolist()
        s = SEED_4_2[grade]
        print(f"  {grade:20s} seed a0 {s[0]:8.0f} m  a1 {s[1]:8.0f} m  a2 {s[2]:+.4f} /°   measured a0 {p[0]:8.1f} m  "
              f"a1 {p[1]:8.0f} m  a2 {p[2]:+.4f} /°")
        print(f"  {'':20s} seed curve at our Δψ: " + ", ".join(f"{v:.0f}" for v in model(dpsi, *s)) + " m")
    return fits


def _bias_label(in_run_bias_s: float | None) -> str:
    return ("table 3-1 bias a turn-on constant" if in_run_bias_s is None
            else f"table 3-1 bias also in-run, drawn anew over {in_run_bias_s / 3600:g} h")


def covariance_table(latitude_deg: float = 40.0, states: int = 20, in_run_bias_s: float | None = None,
                     nhc_sigma: float = 0.05, bias_model: str = "ladder") -> dict:
    """Paper 001 table 4-1 (CEP after 1 h) by covariance analysis of a ``states`` filter, and the eq. 49 fit;
    ``in_run_bias_s``: the grade's bias also an in-run random walk (``grade_errors``); ``bias_model``: the
    grade's bias instability as a Gauss-Markov ladder, one state or a random walk (``grade_errors``); the straight cases'
    error budget (the 1-sigma each error source leaves at the end, metres north / east)."""
    from workbench.grades import load_spec
    from workbench.nav.land_ins import LandInsConfig, covariance_analysis, grade_errors
    from workbench.sim.roads import constant_rate_drive
    from workbench.sim.trajectory import generate, leg_from_dict

    out, budgets = {}, {}
    cfg = LandInsConfig(states=states, nhc_sigma=nhc_sigma)
    t_cpu, t_wall = time.process_time(), time.perf_counter()
    for grade in SEED_4_1:
        ge = grade_errors(load_spec(grade), in_run_bias_s=in_run_bias_s, bias_model=bias_model)
        ceps = []
        for rate in RATES_DPS:
            legs = [leg_from_dict(d) for d in constant_rate_drive(rate)]
            tr = generate(legs, 1.0, np.radians(latitude_deg), np.radians(33.0), 900.0)
            res = covariance_analysis(tr, ge, cfg, budget=rate == 0.0)
            ceps.append(res["cep_m"])
            if rate == 0.0:
                budgets[grade] = {k: np.sqrt(np.clip(np.diag(v)[:2], 0.0, None)).tolist()
                                  for k, v in res["budget"].items()}
        out[grade] = ceps
    t_cpu, t_wall = time.process_time() - t_cpu, time.perf_counter() - t_wall
    dpsi = 3600.0 * np.asarray(RATES_DPS)
    print(f"\npaper 001 table 4-1: CEP after 1 h at 20 m/s (covariance analysis, {states} states, NHC "
          f"{nhc_sigma:g} m/s, {_bias_label(in_run_bias_s)}, bias instability {bias_model}; 16 cases: {t_cpu:.1f} s CPU, "
          f"{t_wall:.1f} s wall; target 60 s)")
    print(f"{'traj':>4s} {'rate °/s':>9s} {'Δψ °':>6s} | {'tactical seed':>13s} {'measured':>9s} | "
          f"{'nav seed':>9s} {'measured':>9s}")
    for i, rate in enumerate(RATES_DPS):
        print(f"{i + 1:4d} {rate:9.4f} {dpsi[i]:6.0f} | {SEED_4_1['tactical_low_noise'][i]:13.0f} "
              f"{out['tactical_low_noise'][i]:9.0f} | {SEED_4_1['navigation_grade'][i]:9.0f} "
              f"{out['navigation_grade'][i]:9.0f}")

    fits = eq49_fit(out, f"covariance, {states} states, {_bias_label(in_run_bias_s)}")
    print("error budget of trajectory 1 (straight), 1-sigma north / east after the hour (m):")
    for name in budgets["tactical_low_noise"]:
        cells = "   ".join(f"{budgets[g][name][0]:8.0f} {budgets[g][name][1]:6.0f}" for g in SEED_4_1)
        print(f"  {name:34s} {cells}")
    return {"rates_dps": list(RATES_DPS), "heading_change_deg": dpsi.tolist(), "cep_m": out, "fit": fits,
            "states": states, "in_run_bias_s": in_run_bias_s, "nhc_sigma_mps": nhc_sigma,
            "budget_straight_m": budgets, "cpu_s": t_cpu, "wall_s": t_wall}


def filter_speed(seed: int = 1) -> float:
    """CPU seconds of one 1-h 100 Hz land-INS filter run (tactical grade, constant 0.3 °/s)."""
    from conftest import calibration_from_truth
    from workbench.grades import draw_unit, load_spec
    from workbench.nav.compensate import compensate, imu_samples
    from workbench.nav.land_ins import LandInsConfig, grade_errors, run_land_ins
    from workbench.session import Site
    from workbench.sim.roads import constant_rate_drive
    from workbench.sim.vehicle import drive, drive_config

    spec = load_spec("tactical_low_noise")
    unit = draw_unit(spec, seed)
    legs = constant_rate_drive(0.3, precalibration=False)
    session, _ = drive(drive_config(legs, Site(40.0, 33.0, 900.0), 0.0), unit, seed)
    samples = compensate(imu_samples(session.samples, 100.0), calibration_from_truth(unit), ("gyro", "accel"))
    run_land_ins(samples.slice(0, 2000), np.radians(40.0), np.radians(33.0), 900.0, 0.0, grade_errors(spec))
    t0, w0 = time.process_time(), time.perf_counter()
    run_land_ins(samples, np.radians(40.0), np.radians(33.0), 900.0, 0.0, grade_errors(spec), LandInsConfig())
    cpu, wall = time.process_time() - t0, time.perf_counter() - w0
    print(f"\none {len(samples) / 360000:.2f}-h 100 Hz land-INS filter run: {cpu:.1f} s CPU ({wall:.1f} s wall); "
          "target 30 s on one core")
    return cpu


def monte_carlo(runs: int, scheduler: str, cruise_s: float, out_dir: Path, states: int = 20,
                deadline: float | None = None, in_run_bias_s: float | None = None) -> dict:
    """Sampled Monte Carlo (``workbench.fleet.land_ins_mc``) of table 4-1 on Dask, resumable in ``out_dir``.

    The runs go run index first (run 0 of every case, then run 1, ...), so an interrupted or
    ``deadline``-stopped (``time.time()``) Monte Carlo has about as many runs of every case.
    """
    from rich.progress import Progress

    from workbench.fleet.batch import cluster_client
    from workbench.fleet.land_ins_mc import McCase, cep_table, monte_carlo as run_mc

    cases = [McCase(g, r, k, cruise_s, True, states, in_run_bias_s) for k in range(runs) for g in SEED_4_1
             for r in RATES_DPS]
    if deadline is None:
        with cluster_client(scheduler) as client, Progress() as bar:
            task = bar.add_task("Monte Carlo", total=len(cases))
            run_mc(cases, out_dir, client, lambda d, n: bar.update(task, completed=d, total=n))
    else:  # one round of runs at a time until the deadline
        for k in range(runs):
            if time.time() > deadline:
                print(f"deadline reached before run {k}", flush=True)
                break
            with cluster_client(scheduler) as client:
                run_mc([c for c in cases if c.run == k], out_dir, client)
            print(f"run {k} of every case done ({time.strftime('%H:%M:%S')})", flush=True)
    out = [json.loads(c.path(out_dir).read_text()) for c in cases if c.path(out_dir).exists()]
    table = cep_table(out)
    print(f"\nsampled Monte Carlo, up to {runs} run(s) per case, {states}-state filter, cruise {cruise_s:g} s, "
          f"{_bias_label(in_run_bias_s)} "
          f"(results in {out_dir}); CEP = median final horizontal error:")
    print(f"{'traj':>4s} {'rate °/s':>9s} | {'tactical seed':>13s} {'MC CEP':>9s} {'σ':>8s} {'e/σ':>5s} {'runs':>4s} | "
          f"{'nav seed':>9s} {'MC CEP':>9s} {'σ':>8s} {'e/σ':>5s} {'runs':>4s}   (e/σ: median of the final horizontal "
          "error over the filter's sigma, 0.83 for a consistent filter)")
    ratio: dict = {}
    for o in out:
        c = o["case"]
        ratio.setdefault((c["grade"], c["rate_dps"]), []).append(o["final_error_m"] / o["final_sigma_m"])
    ceps: dict[str, list[float]] = {g: [] for g in SEED_4_1}
    suffix = ("" if states == 20 else f" s{states}") + ("" if in_run_bias_s is None else f" b{in_run_bias_s:g}")
    for i, rate in enumerate(RATES_DPS):
        cells = []
        for g in SEED_4_1:
            v = table.get(f"{g} {rate:g}{suffix}")
            ceps[g].append(v["cep_m"] if v else np.nan)
            cells.append(f"{SEED_4_1[g][i]:9.0f} {v['cep_m']:9.1f} {v['sigma_m']:8.1f} "
                         f"{np.median(ratio[(g, rate)]):5.2f} {v['runs']:4d}" if v
                         else f"{SEED_4_1[g][i]:9.0f} {'-':>9s} {'-':>8s} {'-':>5s} {0:4d}")
        print(f"{i + 1:4d} {rate:9.4f} | {cells[0]:>43s} | {cells[1]}")
    complete = {g: v for g, v in ceps.items() if np.all(np.isfinite(v))}
    fits = eq49_fit(complete, f"sampled Monte Carlo, {states} states") if complete else {}
    return {"table": table, "fit": fits}


def main() -> None:
    from workbench.nav.land_ins_model import BIAS_MODELS

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--skip-lns", action="store_true", help="leave out the thesis drive (~2 min)")
    ap.add_argument("--filter-speed", action="store_true", help="time one 1-h 100 Hz land-INS run")
    ap.add_argument("--out", type=Path, help="write the measured figures as JSON")
    ap.add_argument("--monte-carlo", type=int, default=0, metavar="RUNS", help="sampled Monte Carlo runs per case")
    ap.add_argument("--scheduler", default="local", help="Dask scheduler: local (127.0.0.1) or tcp://HOST:PORT")
    ap.add_argument("--cruise-s", type=float, default=3600.0, help="cruise of the Monte Carlo drives, s")
    ap.add_argument("--mc-dir", type=Path, default=Path("/tmp/seed_tables_mc"), help="resumable Monte Carlo results")
    ap.add_argument("--states", type=int, default=20, help="filter states: 20 (paper 001), 29 or 38 (+ scale factor "
                    "and misalignment of the gyro / of both triads)")
    ap.add_argument("--skip-covariance", action="store_true", help="leave out the covariance tables")
    ap.add_argument("--in-run-bias-h", type=float, default=5.0, metavar="H",
                    help="second covariance table (and the Monte Carlo with --mc-in-run): table 3-1's bias also "
                         "in-run, drawn anew over H hours (paper 001's bias instability noise, not in table 3-1; "
                         "0 = no second table)")
    ap.add_argument("--mc-in-run", action="store_true", help="the Monte Carlo with the in-run bias of --in-run-bias-h")
    ap.add_argument("--nhc-sigma", type=float, default=0.05, help="NHC measurement 1-sigma of the covariance "
                    "tables, m/s (not given by the paper)")
    ap.add_argument("--until", default=None, help="stop the Monte Carlo after the round running at HH:MM UTC")
    ap.add_argument("--bias-model", default="ladder", choices=BIAS_MODELS,
                    help="the grades' bias instability in the covariance tables' filter (the Monte Carlo's: "
                         "grade_errors' default)")
    args = ap.parse_args()
    in_run_s = args.in_run_bias_h * 3600.0 if args.in_run_bias_h > 0 else None
    doc = {}
    if not args.skip_covariance:
        doc["table_4_1"] = covariance_table(states=args.states, nhc_sigma=args.nhc_sigma, bias_model=args.bias_model)
        if in_run_s is not None:
            doc["table_4_1_in_run_bias"] = covariance_table(states=args.states, in_run_bias_s=in_run_s,
                                                            nhc_sigma=args.nhc_sigma, bias_model=args.bias_model)
    if not args.skip_lns:
        lns = lns_tables()
        doc["tables_2_8_2_9"] = {m: {v: lns[m][v]["error_pct"] for v in ("sf_state", "no_sf_state")}
                                 for m in ("raw", "calibrated", "wrong_bias")}
    if args.filter_speed:
        doc["filter_cpu_s"] = filter_speed()
    if args.monte_carlo:
        deadline = None
        if args.until:
            import calendar

            hh, mm = map(int, args.until.split(":"))
            now = time.gmtime()
            deadline = calendar.timegm((now.tm_year, now.tm_mon, now.tm_mday, hh, mm, 0))
        doc["monte_carlo"] = monte_carlo(args.monte_carlo, args.scheduler, args.cruise_s, args.mc_dir, args.states,
                                         deadline, in_run_s if args.mc_in_run else None)
    if args.out:
        args.out.write_text(json.dumps(doc, indent=1))


if __name__ == "__main__":
    main()
