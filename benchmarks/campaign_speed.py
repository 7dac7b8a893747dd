"""Speed of the main job: the whole simulated campaign, per procedure (wall, CPU, peak memory).

Runs what ``workbench run campaign --unit fixtures/units/industrial_mems.yaml --rig sim`` runs
(recording, analysis, figures, the merged set; no store) in this process and prints, per
procedure, the wall time, the CPU time and the peak resident memory while it ran (sampled every
20 ms from /proc), then the totals and the process's peak. On a shared machine the wall time
depends on the load: the CPU time is the fairer figure, and ``--repeat`` takes the run with the
least CPU. ``--no-figures`` leaves the figures out, ``--out`` keeps the outputs (compare
calibration.json with an earlier run: same seed, same numbers).

    python benchmarks/campaign_speed.py [--unit fixtures/units/industrial_mems.yaml] [--seed 1]
        [--repeat 1] [--out DIR] [--no-figures]

Target of issue 23: the whole campaign under 10 s wall on 2 cores.
"""

from __future__ import annotations

import argparse
import inspect
import os
import resource
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


class _Peak(threading.Thread):
    """Samples this process's resident set size; :meth:`reset` starts a new window."""

    def __init__(self, period_s: float = 0.02) -> None:
        super().__init__(daemon=True)
        self.period_s, self.peak, self._stop = period_s, 0, threading.Event()
        self._page = os.sysconf("SC_PAGE_SIZE")

    def rss(self) -> int:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * self._page

    def reset(self) -> int:
        peak, self.peak = max(self.peak, self.rss()), self.rss()
        return peak

    def run(self) -> None:
        while not self._stop.wait(self.period_s):
            self.peak = max(self.peak, self.rss())

    def stop(self) -> None:
        self._stop.set()


def campaign(unit: str, seed: int, out_dir: Path, figures: bool) -> list[tuple[str, float, float, int]]:
    """Run the campaign once; (procedure, wall s, CPU s, peak bytes) per procedure."""
    from workbench.grades import draw_unit, load_spec
    from workbench.jobs import run_campaign
    from workbench.rigconfig import load_rig_config

    spec, cfg = load_spec(unit), load_rig_config("sim")
    truth = draw_unit(spec, seed)
    rows: list[tuple[str, float, float, int]] = []
    sampler = _Peak()
    sampler.start()
    mark = {"name": None, "wall": time.perf_counter(), "cpu": time.process_time()}

    def close(next_name: str | None) -> None:
        wall, cpu = time.perf_counter(), time.process_time()
        peak = sampler.reset()
        if mark["name"] is not None:
            rows.append((mark["name"], wall - mark["wall"], cpu - mark["cpu"], peak))
        mark.update(name=next_name, wall=wall, cpu=cpu)

    def progress_for(name: str):
        close(name)
        return None

    kwargs = {} if figures or "figures" not in inspect.signature(run_campaign).parameters else {"figures": False}
    run_campaign(spec, truth, cfg, seed, out_dir, None, progress_for, **kwargs)
    close(None)
    sampler.stop()
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--unit", default=str(ROOT / "fixtures/units/industrial_mems.yaml"))
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--out", type=Path, default=None, help="Keep the outputs here (default: a temporary folder).")
    parser.add_argument("--no-figures", action="store_true")
    args = parser.parse_args()
    t0, c0 = time.perf_counter(), time.process_time()
    import workbench.jobs  # noqa: F401 - the imports are start-up, not campaign
    print(f"imports: {time.perf_counter() - t0:.2f} s wall, {time.process_time() - c0:.2f} s CPU")
    best = None
    for k in range(args.repeat):
        with tempfile.TemporaryDirectory() as tmp:
            out = args.out / f"run{k}" if args.out else Path(tmp) / "campaign"
            rows = campaign(args.unit, args.seed, out, not args.no_figures)
        if best is None or sum(r[2] for r in rows) < sum(r[2] for r in best):
            best = rows
    print(f"{'procedure':14s} {'wall s':>8s} {'CPU s':>8s} {'peak MB':>8s}")
    for name, wall, cpu, peak in best:
        print(f"{name:14s} {wall:8.2f} {cpu:8.2f} {peak / 1e6:8.0f}")
    print(f"{'campaign':14s} {sum(r[1] for r in best):8.2f} {sum(r[2] for r in best):8.2f} "
          f"{max(r[3] for r in best) / 1e6:8.0f}")
    print(f"process peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3:.0f} MB; "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
