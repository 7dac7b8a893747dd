"""Time of ``workbench certificate`` for a stored set: wall and CPU per stage, and the whole command.

Stages, in one interpreter: importing the CLI and the certificate module, opening the store and
reading the set, rendering the HTML, printing the PDF with Chromium (CPU of the browser counted
as the children's). Then the whole command ``--repeat`` times in fresh interpreters (median and
minimum of wall and CPU, children included). On a shared machine the CPU time is the fair figure;
load only adds wall time.

    WORKBENCH_DB=sqlite:///path/wb.db python benchmarks/certificate_speed.py SET_ID [--repeat 3]

Target of issue 18: the campaign's set (``workbench run campaign --unit
fixtures/units/industrial_mems.yaml --rig sim``) printed in under 5 s.
"""

from __future__ import annotations

import argparse
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _cpu() -> tuple[float, float]:
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime, kids.ru_utime + kids.ru_stime


def stages(set_id: str, folder: Path) -> None:
    """Print wall / CPU (own, children) of each stage of one certificate."""
    marks = [("start", time.monotonic(), *_cpu())]

    def mark(name: str) -> None:
        marks.append((name, time.monotonic(), *_cpu()))

    import workbench.cli  # noqa: F401 - the command's own start-up

    mark("import cli")
    from workbench.fleet.certificate import print_pdf, render_certificate

    mark("import certificate")
    from workbench.store import Store

    store = Store()
    cal = store.get_set(set_id)
    mark("store + set")
    html = folder / "certificate.html"
    html.write_text(render_certificate(cal, store))
    mark("HTML")
    chromium = shutil.which("chromium")
    if chromium:
        print_pdf(html, html.with_suffix(".pdf"), chromium)
        mark("PDF (Chromium)")
    for (_, t0, s0, c0), (name, t, s, c) in zip(marks, marks[1:]):
        print(f"{name:20s} wall {t - t0:6.2f} s   CPU {s - s0:5.2f} s   children {c - c0:5.2f} s")


def whole(set_id: str, folder: Path, repeat: int) -> None:
    """Median and minimum wall and CPU time (children included) of the whole command."""
    walls, cpus = [], []
    for _ in range(repeat):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.monotonic()
        subprocess.run([sys.executable, "-m", "workbench", "certificate", set_id, "--out",
                        str(folder / "cmd.html")], check=True, capture_output=True)
        walls.append(time.monotonic() - t0)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpus.append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
    print(f"workbench certificate: wall median {statistics.median(walls):.2f} s (min {min(walls):.2f}), "
          f"CPU median {statistics.median(cpus):.2f} s (min {min(cpus):.2f}), {repeat} runs")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("set_id")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        stages(args.set_id, Path(tmp))
        whole(args.set_id, Path(tmp), args.repeat)


if __name__ == "__main__":
    main()
