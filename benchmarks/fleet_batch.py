"""Fleet batch benchmark: N simulated units' multi-position sessions, serial vs a 2-worker LocalCluster.

Prints both wall times, their ratio, and whether the calibrations are identical. With
``--allan-samples`` it also writes a long single-channel-per-axis Allan session and reports the
peak resident memory of a worker analysing it (bounded-memory streaming path).

    python -m benchmarks.fleet_batch --units 100 --workers 2 [--allan-samples 100000000]   (from the repo root)
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from workbench.fleet.batch import cluster_client, run_batch
from workbench.fleet.simulate import simulate_fleet


def _coefficients(report) -> dict:
    out = {}
    for o in report.succeeded:
        cal = json.loads(o["calibration"])
        out[o["session_dir"]] = {t: (cal[t]["bias"], cal[t]["scale_misalignment"]) for t in ("accel", "gyro")}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--units", type=int, default=100)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--dwell", type=float, default=60.0, help="dwell per position, s")
    ap.add_argument("--allan-samples", type=int, default=0, help="samples of the long Allan session (0 = skip)")
    ap.add_argument("--dir", type=Path, default=None)
    args = ap.parse_args()
    work = args.dir or Path(tempfile.mkdtemp(prefix="wb-fleet-"))
    t0 = time.perf_counter()
    dirs = simulate_fleet("industrial_mems", args.units, "multiposition", work / "sessions",
                          options={"dwell_s": args.dwell})
    print(f"simulated {len(dirs)} units in {time.perf_counter() - t0:.1f} s -> {work}")
    t0 = time.perf_counter()
    serial = run_batch("multiposition", dirs)
    t_serial = time.perf_counter() - t0
    t0 = time.perf_counter()
    with cluster_client("local", args.workers) as client:
        t_start = time.perf_counter() - t0
        t0 = time.perf_counter()
        parallel = run_batch("multiposition", dirs, client)  # first batch: workers import the library
        t_parallel = time.perf_counter() - t0
        t0 = time.perf_counter()
        warm = run_batch("multiposition", dirs, client)
        t_warm = time.perf_counter() - t0
    same = _coefficients(serial) == _coefficients(parallel) == _coefficients(warm)
    print(f"serial (this process, library imported): {t_serial:8.1f} s ({len(serial.succeeded)} ok, "
          f"{len(serial.failures)} failed)")
    print(f"LocalCluster x{args.workers} start-up:              {t_start:8.1f} s")
    print(f"LocalCluster x{args.workers}, first batch:          {t_parallel:8.1f} s  speed-up {t_serial / t_parallel:5.2f}x")
    print(f"LocalCluster x{args.workers}, warm workers:         {t_warm:8.1f} s  speed-up {t_serial / t_warm:5.2f}x")
    print(f"results identical: {same}")
    if args.allan_samples:
        from benchmarks.allan_session_memory import worker_peak_memory

        peak, seconds = worker_peak_memory(args.allan_samples, work / "allan")
        print(f"Allan session of {args.allan_samples:.0e} samples: worker peak RSS {peak / 2**20:.0f} MiB, "
              f"{seconds:.1f} s")


if __name__ == "__main__":
    main()
