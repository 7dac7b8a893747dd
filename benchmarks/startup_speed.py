"""Start-up time of the command line as a user types it: ``workbench --help`` and ``workbench sets list``.

Runs each command ``--repeat`` times, interleaved, each in a fresh interpreter, and prints the
median and the minimum of the wall time and of the CPU time (user + system of the child) with
the issue 23 target beside each command and the load average before and after. The commands
are the console script of the interpreter running this file (``<venv>/bin/workbench``, what a
user types), with, for scale, ``python -c pass``, the import of the CLI framework alone and
``python -m workbench sets list``; the workbench they run is this checkout's (``PYTHONPATH``).
``sets list`` lists a store holding one calibration set (a multi-position calibration of the
simulated rig, recorded into a temporary folder first).

Byte code: a user's installed workbench has its ``.pyc`` files from the second command on
(``pip install -e .`` writes none for the project's own modules; the first command does, unless
the shell says ``PYTHONDONTWRITEBYTECODE=1``, as this machine's does). Each command is timed both
ways, interleaved: ``cached`` (this checkout, ``PYTHONDONTWRITEBYTECODE`` removed and every
command run once before the timed runs, so the byte code is written) and ``source`` (a copy of
the checkout without ``__pycache__`` and ``PYTHONDONTWRITEBYTECODE=1``: every project module
compiled on every run; the libraries keep the byte code pip wrote). Measured on this 2-core
machine at load 3 (medians): ``--help`` 0.19 s cached, 0.24 s from source; ``sets list`` 0.24 s
and 0.32 s; the byte code is worth 0.03-0.08 s, not the 0.3 s seen between sessions, which was
the load. On a shared machine the minimum wall time is the fairer figure: load only ever adds time.

    python benchmarks/startup_speed.py [--repeat 9]

Targets of issue 23: ``--help`` under 0.3 s, ``sets list`` under 0.5 s wall.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = str(Path(sys.executable).parent / "workbench")  # the console script of this venv
COMMANDS = {
    "python -c pass": [sys.executable, "-c", "pass"],
    "import typer+rich": [sys.executable, "-c", "import typer, typer.rich_utils, rich.console, rich.table"],
    "workbench --help": [SCRIPT, "--help"],
    "workbench sets list": [SCRIPT, "sets", "list"],
    "python -m workbench sets list": [sys.executable, "-m", "workbench", "sets", "list"],
}
TARGET_S = {"workbench --help": 0.3, "workbench sets list": 0.5}  # wall, issue 23


def _run(command: list[str], env: dict, cwd: str) -> tuple[float, float]:
    """(wall s, CPU s) of one command in a fresh interpreter."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(command, env=env, cwd=cwd, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=9)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        base = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        base.update(WORKBENCH_DB=f"sqlite:///{Path(tmp) / 'wb.db'}", WORKBENCH_WORKERS="1")
        source = Path(tmp) / "source"  # the checkout's code without byte code
        for package in ("workbench", "procedures"):
            shutil.copytree(ROOT / package, source / package, ignore=shutil.ignore_patterns("__pycache__"))
        envs = {"cached": {**base, "PYTHONPATH": str(ROOT)},
                "source": {**base, "PYTHONPATH": str(source), "PYTHONDONTWRITEBYTECODE": "1"}}
        subprocess.run([SCRIPT, "run", "multiposition", "--unit", str(ROOT / "fixtures/units/industrial_mems.yaml"),
                        "--rig", "sim", "--out", str(Path(tmp) / "run"), "--no-figures"],
                       env=envs["cached"], cwd=tmp, check=True, capture_output=True)  # a store with one set
        for command in COMMANDS.values():  # the byte code written, as after a user's first command
            _run(command, envs["cached"], tmp)
        load = os.getloadavg()[0]
        times: dict[tuple[str, str], list[tuple[float, float]]] = {(n, m): [] for n in COMMANDS for m in envs}
        for _ in range(args.repeat):
            for name, command in COMMANDS.items():
                for mode, env in envs.items():
                    times[name, mode].append(_run(command, env, tmp))
    print(f"{'command':30s} {'byte code':>9s} {'wall med':>9s} {'wall min':>9s} {'CPU med':>9s} {'CPU min':>9s} "
          f"{'target':>8s}")
    for (name, mode), runs in times.items():
        wall, cpu = [w for w, _ in runs], [c for _, c in runs]
        target = f"< {TARGET_S[name]:.1f}" if name in TARGET_S else ""
        print(f"{name:30s} {mode:>9s} {statistics.median(wall):9.3f} {min(wall):9.3f} {statistics.median(cpu):9.3f} "
              f"{min(cpu):9.3f} {target:>8s}")
    print(f"load average {load:.1f} before, {os.getloadavg()[0]:.1f} after, on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
