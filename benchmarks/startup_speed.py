"""Start-up time of the command line: ``workbench --help`` and ``workbench sets list``.

Runs each command (and, for scale, ``python -c pass`` and the import of the CLI framework
alone) ``--repeat`` times, interleaved, each in a fresh interpreter, and prints the median and
the minimum of the wall time and of the CPU time (user + system of the child). On a shared
machine the minimum wall time is the fairer figure: load only ever adds time. ``sets list``
runs against an existing, empty store in a temporary folder.

    python benchmarks/startup_speed.py [--repeat 9]

Targets of issue 23: ``--help`` under 0.3 s, ``sets list`` under 0.5 s wall.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
COMMANDS = {
    "python -c pass": ["-c", "pass"],
    "import typer+rich": ["-c", "import typer, typer.rich_utils, rich.console, rich.table"],
    "workbench --help": ["-m", "workbench", "--help"],
    "workbench sets list": ["-m", "workbench", "sets", "list"],
}


def _run(args: list[str], env: dict, cwd: str) -> tuple[float, float]:
    """(wall s, CPU s) of one ``python ARGS`` in a fresh interpreter."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, *args], env=env, cwd=cwd, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=9)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "PYTHONPATH": str(ROOT), "WORKBENCH_DB": f"sqlite:///{Path(tmp) / 'wb.db'}"}
        subprocess.run([sys.executable, "-m", "workbench", "db", "upgrade"], env=env, cwd=tmp, check=True,
                       capture_output=True)
        times: dict[str, list[tuple[float, float]]] = {name: [] for name in COMMANDS}
        for _ in range(args.repeat):
            for name, command in COMMANDS.items():
                times[name].append(_run(command, env, tmp))
    print(f"{'command':22s} {'wall med':>9s} {'wall min':>9s} {'CPU med':>9s} {'CPU min':>9s}")
    for name, runs in times.items():
        wall, cpu = [w for w, _ in runs], [c for _, c in runs]
        print(f"{name:22s} {statistics.median(wall):9.3f} {min(wall):9.3f} {statistics.median(cpu):9.3f} "
              f"{min(cpu):9.3f}")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
