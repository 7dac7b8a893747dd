"""Fleet batch benchmark: N simulated units' multi-position sessions, serial vs a 2-worker LocalCluster.

Both paths write every result to their own SQLite store, as ``workbench batch`` does. Prints
both wall times, their ratio, whether the results are identical (every number of the result
and the calibration set; only the set's id and creation time differ), and where the time
goes: cluster start-up and the workers' library import apart from the analysis; the
analysis and the store writes; CPU seconds of the submitting process (client, scheduler,
store) and of the workers; the workers' busy time; and the CPU floor, the least wall time the
batch's CPU seconds allow on idle cores (the machine is shared, so wall times vary with the
other jobs; CPU seconds much less). ``--repeat N`` (default 2) alternates N serial runs and N
cluster runs, each on a fresh cluster, and compares the best wall time of each. With
``--allan-samples`` it also writes a long single-channel-per-axis Allan session and reports the
peak resident memory of a worker analysing it (bounded-memory streaming path).

    python -m benchmarks.fleet_batch --units 100 --workers 2 [--allan-samples 100000000]   (from the repo root)

``--dir D --reuse`` analyses the sessions already simulated under ``D/sessions``.
"""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time
from pathlib import Path

import workbench.fleet.batch as batch_mod
from workbench.fleet.batch import cluster_client, run_batch, warm_up
from workbench.fleet.simulate import simulate_fleet
from workbench.store import Store

VARYING = ("id", "created")  # of a calibration set: new for every analysis
WORKER_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MALLOC_TRIM_THRESHOLD_")


def _numbers(report) -> dict:
    """Per session: the result and the calibration set without the per-analysis id and timestamp."""
    out = {}
    for o in report.succeeded:
        cal = {k: v for k, v in o["calibration"].to_dict().items() if k not in VARYING}
        out[o["session_dir"]] = ({k: v for k, v in o["result"].items() if k != "calibration_id"}, cal)
    return out


def _cpu() -> float:
    """CPU seconds of this process (all threads: client, scheduler, nannies, store writes)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _worker_cpu() -> float:
    return time.process_time()


class _StoreTimer:
    """Wall seconds spent in ``store_outcomes`` (the submitting process's store writes)."""

    def __init__(self) -> None:
        self.seconds, self._real = 0.0, batch_mod.store_outcomes

    def __call__(self, store, outcomes) -> None:
        t0 = time.perf_counter()
        self._real(store, outcomes)
        self.seconds += time.perf_counter() - t0


def _timed_batch(dirs, db: Path, client=None) -> dict:
    """One batch into a fresh store: wall, store and CPU seconds, and (on a cluster) worker busy time."""
    timer = _StoreTimer()
    batch_mod.store_outcomes = timer
    store = Store(f"sqlite:///{db}")
    w0 = client.run(_worker_cpu) if client else {}
    c0, t0 = _cpu(), time.perf_counter()
    try:
        if client is None:
            report = run_batch("multiposition", dirs, None, store)
            busy = {}
        else:
            from distributed import get_task_stream

            with get_task_stream(client) as ts:
                report = run_batch("multiposition", dirs, client, store)
            busy = {}
            for rec in ts.data:
                for s in rec["startstops"]:
                    if s["action"] == "compute":
                        busy[rec["worker"]] = busy.get(rec["worker"], 0.0) + s["stop"] - s["start"]
    finally:
        batch_mod.store_outcomes = timer._real
    wall, cpu = time.perf_counter() - t0, _cpu() - c0
    w1 = client.run(_worker_cpu) if client else {}
    stored = len(store.list_results("multiposition"))
    return {"report": report, "wall": wall, "store": timer.seconds, "cpu": cpu, "stored": stored,
            "worker_cpu": sum(w1[k] - w0[k] for k in w0), "busy": busy}


def _line(label: str, r: dict, serial_wall: float | None = None) -> str:
    rep = r["report"]
    text = (f"{label:<34} {r['wall']:7.1f} s  ({len(rep.succeeded)} ok, {len(rep.failures)} failed, "
            f"{r['stored']} stored; store writes {r['store']:.1f} s, this process {r['cpu']:.1f} CPU-s")
    if r["busy"]:
        text += (f", workers {r['worker_cpu']:.1f} CPU-s, busy "
                 + " + ".join(f"{v:.1f}" for v in r["busy"].values()) + " s")
    text += ")"
    if serial_wall is not None:
        text += f"  speed-up {serial_wall / r['wall']:4.2f}x"
    return text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--units", type=int, default=100)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--dwell", type=float, default=60.0, help="dwell per position, s")
    ap.add_argument("--allan-samples", type=int, default=0, help="samples of the long Allan session (0 = skip)")
    ap.add_argument("--dir", type=Path, default=None)
    ap.add_argument("--reuse", action="store_true", help="analyse the sessions already under DIR/sessions")
    ap.add_argument("--repeat", type=int, default=2, help="serial/cluster pairs (the best of each is compared)")
    args = ap.parse_args()
    work = args.dir or Path(tempfile.mkdtemp(prefix="wb-fleet-"))
    sessions = work / "sessions"
    t0 = time.perf_counter()
    if args.reuse and sessions.is_dir():
        dirs = sorted(p for p in sessions.iterdir() if (p / "session.json").is_file())[:args.units]
        print(f"reusing {len(dirs)} sessions under {sessions}")
    else:
        dirs = simulate_fleet("industrial_mems", args.units, "multiposition", sessions,
                              options={"dwell_s": args.dwell})
        print(f"simulated {len(dirs)} units in {time.perf_counter() - t0:.1f} s -> {work}")
    for db in work.glob("bench-*.db*"):
        db.unlink()
    cores = os.cpu_count() or 1
    print(f"load average before: {os.getloadavg()[0]:.2f} ({cores}-core machine shared with other jobs)")
    runs, reports = [], []
    for k in range(args.repeat):  # alternate, so that both paths see the other jobs' load alike
        serial = _timed_batch(dirs, work / f"bench-serial{k}.db")
        t0 = time.perf_counter()
        with cluster_client("local", args.workers) as client:
            t_cluster = time.perf_counter() - t0
            t0 = time.perf_counter()
            imports = warm_up(client, "multiposition")
            t_warm = time.perf_counter() - t0
            env = set(map(tuple, client.run(lambda: [os.environ.get(v) for v in WORKER_VARS]).values()))
            batch = _timed_batch(dirs, work / f"bench-cluster{k}.db", client)
        reports += [serial["report"], batch["report"]]
        print(f"run {k + 1} (load average {os.getloadavg()[0]:.2f})")
        print("  " + _line("serial (this process)", serial))
        print(f"  LocalCluster x{args.workers} start-up:             {t_cluster:7.1f} s")
        print(f"  worker warm-up (library import):   {t_warm:7.1f} s  (per worker "
              + ", ".join(f"{v:.1f}" for v in imports.values()) + f" s; worker {', '.join(WORKER_VARS)}: {env})")
        print("  " + _line(f"LocalCluster x{args.workers}, warm workers", batch, serial["wall"]))
        # with the machine to itself, the batch cannot take less wall time than its CPU seconds
        # spread over the cores (client, scheduler and workers share them), nor than a worker's share
        floor = max((batch["cpu"] + batch["worker_cpu"]) / cores, batch["worker_cpu"] / args.workers)
        print(f"  CPU floor of the batch on {cores} idle cores: {floor:5.1f} s (this process + workers "
              f"{batch['cpu'] + batch['worker_cpu']:.1f} CPU-s); serial CPU {serial['cpu']:.1f} s: "
              f"{serial['cpu'] / floor:4.2f}x")
        runs.append((serial["wall"], t_cluster + t_warm, batch["wall"]))
    best = [min(r[i] for r in runs) for i in range(3)]
    print(f"best of {args.repeat}: serial {best[0]:.1f} s; LocalCluster x{args.workers} start-up {best[1]:.1f} s "
          f"+ analysis {best[2]:.1f} s; speed-up {best[0] / best[2]:.2f}x (analysis), "
          f"{best[0] / (best[1] + best[2]):.2f}x (with start-up)")
    same = all(_numbers(r) == _numbers(reports[0]) for r in reports[1:])
    print(f"results identical: {same}")
    if args.allan_samples:
        from benchmarks.allan_session_memory import worker_peak_memory

        peak, seconds = worker_peak_memory(args.allan_samples, work / "allan")
        print(f"Allan session of {args.allan_samples:.0e} samples: worker peak RSS {peak / 2**20:.0f} MiB, "
              f"{seconds:.1f} s")


if __name__ == "__main__":
    main()
