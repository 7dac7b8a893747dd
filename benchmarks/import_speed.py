"""CPU time of importing a long multi-stream recording with arrival stamps (4 CSV streams, MARG layout).

    python benchmarks/import_speed.py --hours 3

Writes a still recording (accelerometer, gyroscope and temperature at 100 Hz from one read, a
magnetometer at 77 Hz) with the virtual lab's bursty arrival stamps and two recorder pauses into a
temporary folder, imports it through fixtures/import_profiles/marg_mpu6050_hmc5883l.yaml and prints
the CPU time of each stage (read + clock fits, merge, axis check, write) and the peak RSS.
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _write(path: Path, header: str, t: np.ndarray, values: np.ndarray) -> None:
    np.savetxt(path, np.column_stack([t, values]), delimiter=",", header=header, comments="", fmt="%.10g")


def main() -> None:
    from workbench.importer import import_file
    from workbench.sim.arrival import arrival_stamps

    ap = argparse.ArgumentParser()
    ap.add_argument("--hours", type=float, default=3.0)
    hours = ap.parse_args().hours
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp) / "rec"
        d.mkdir()
        n = int(hours * 3600 * 100)
        t = 1.0 + np.arange(n) / 100.0
        keep = np.ones(n, bool)
        keep[n // 3:n // 3 + 200] = keep[2 * n // 3:2 * n // 3 + 300] = False
        t = t[keep]
        a = arrival_stamps(t, 1)
        m = len(t)
        acc = np.c_[0.01 * rng.standard_normal((m, 2)), 1 + 0.01 * rng.standard_normal(m)]
        _write(d / "accelerometer.csv", "t_s,ax_g,ay_g,az_g", a, acc)
        _write(d / "gyroscope.csv", "t_s,gx_dps,gy_dps,gz_dps", a, 0.3 * rng.standard_normal((m, 3)))
        _write(d / "temperature.csv", "t_s,temp_c", a, 23 + 0.01 * rng.standard_normal((m, 1)))
        tm = 1.0 + np.arange(int(hours * 3600 * 77)) / 77.0
        pauses = ((tm > t[n // 3 - 1]) & (tm < t[n // 3])) | ((tm > t[2 * n // 3 - 201]) & (tm < t[2 * n // 3 - 200]))
        tm = tm[~pauses]
        _write(d / "magnetometer.csv", "t_s,mx_gauss,my_gauss,mz_gauss", arrival_stamps(tm, 2),
               np.c_[0.2 + 0.002 * rng.standard_normal(len(tm)), 0.002 * rng.standard_normal(len(tm)), 0.43 + 0 * tm])
        c0, w0 = time.process_time(), time.perf_counter()
        s = import_file(ROOT / "fixtures" / "import_profiles" / "marg_mpu6050_hmc5883l.yaml", d, Path(tmp) / "s")
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"{hours:g} h, {len(s.samples)} samples, {len(s.steps)} steps: import {cpu:.1f} s CPU ({wall:.1f} s wall), "
          f"peak RSS {rss:.0f} MB")


if __name__ == "__main__":
    main()
