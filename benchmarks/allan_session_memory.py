"""Peak memory of a batch worker analysing one long Allan session (bounded-memory streaming path).

Writes a single-hold ``allan`` session (``session.json`` + ``samples.parquet``, row groups of
1e6 rows, written chunk by chunk: the writer's memory is bounded too) of ``n_samples`` samples
at 100 Hz with the required columns only (t, step, gx..az, SI float64), then runs
:func:`workbench.fleet.batch.analyze_one` ("allan") in a fresh Python process, as a Dask worker
would, and reports that process's peak resident set size and the wall time.

Simulated unit (industrial MEMS, thesis table 1.1 level), per axis: white rate noise (ARW
0.2 °/√h; VRW 0.05 m/s/√h), flicker bias (B 8 °/h; 50 µg) as a sum of independent first-order
Gauss-Markov processes with correlation times 2 s .. 2^17 s spaced by 4 (equal variances
sigma_i^2 = B^2 ln4 / pi: their summed one-sided PSD approximates B^2 / (pi f), whose AVAR
is (2 ln2 / pi) B^2, the IEEE 952 flicker term; measured on the 1 Hz grid: ADEV within 3 % of
0.664 B from 16 s to 16 000 s, up to 25 % lower at 1-8 s and beyond 30 000 s), generated at 1 Hz
and held (the white noise dominates the short taus), and rate random walk (K 2 °/h/√h;
20 µg/√h), on top of the Earth rate (+ a 5 °/h bias) and normal gravity of a level z-down mount
at 40.8° N (so the session's unit checks pass).

    python benchmarks/allan_session_memory.py 1e8 [--dir /tmp/wb-allan-mem] [--keep]
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from scipy.signal import lfilter

from workbench.earth import normal_gravity
from workbench.session import FORMAT, REQUIRED_COLUMNS

RATE = 100.0  # Hz
ROWS = 1_000_000  # rows per written chunk and Parquet row group (a multiple of RATE)
LAT = np.radians(40.8)
OMEGA = 7.292115e-5  # rad/s, Earth rate
DEG_H = np.pi / 180.0 / 3600.0  # rad/s per °/h
# per triad: white density (SI/√Hz), flicker B (SI), RRW K (SI/s/√Hz)
NOISE = {"g": (0.2 * np.pi / 180.0 / 60.0, 8.0 * DEG_H, 2.0 * DEG_H / 60.0),
         "a": (0.05 / 60.0, 50e-6 * 9.80665, 20e-6 * 9.80665 / 60.0)}
FLICKER_T = 2.0 * 4.0 ** np.arange(9)  # s, Gauss-Markov correlation times (2 s .. 2^17 s)
_WORKER = """
import json, resource, sys, time
from workbench.fleet.batch import analyze_one
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = time.perf_counter()
out = analyze_one("allan", sys.argv[1])
seconds = time.perf_counter() - t0
cal = out["calibration"].to_dict() if out["ok"] else None
print(json.dumps({"ok": out["ok"], "error": out.get("error"), "seconds": seconds, "import_rss_kib": base,
                  "peak_rss_kib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
                  "noise": None if cal is None else cal["noise"]}))
"""


def write_session(n_samples: int, directory: Path, seed: int = 1) -> Path:
    """Write an ``n_samples``-sample single-hold Allan session into ``directory`` (bounded memory)."""
    directory.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    # body = NED (z-down mount, table zero north): Earth rate + bias; specific force -g along z
    const = {"g": np.array([OMEGA * np.cos(LAT), 0.0, -OMEGA * np.sin(LAT)]) + 5.0 * DEG_H,
             "a": np.array([0.0, 0.0, -normal_gravity(LAT, 0.0)])}
    dt = 1.0 / RATE
    phi = np.exp(-1.0 / FLICKER_T)  # AR(1) coefficients at the 1 Hz flicker grid
    gm_state = {k: np.zeros((len(FLICKER_T), 3)) for k in NOISE}
    rrw_state = {k: np.zeros(3) for k in NOISE}
    schema = pa.schema([("t", pa.float64()), ("step", pa.int64())] + [(c, pa.float64()) for c in REQUIRED_COLUMNS[2:]])
    hold = int(RATE)  # samples per flicker grid point
    with pq.ParquetWriter(directory / "samples.parquet", schema, compression="snappy", use_dictionary=["step"]) as w:
        for start in range(0, n_samples, ROWS):
            n = min(ROWS, n_samples - start)
            cols = {"t": np.arange(start, start + n) * dt, "step": np.zeros(n, np.int64)}
            for k, names in (("g", REQUIRED_COLUMNS[2:5]), ("a", REQUIRED_COLUMNS[5:8])):
                white, b, kk = NOISE[k]
                y = const[k] + white * np.sqrt(RATE) * rng.standard_normal((n, 3))
                steps = np.cumsum(kk * np.sqrt(dt) * rng.standard_normal((n, 3)), axis=0) + rrw_state[k]
                rrw_state[k] = steps[-1].copy()
                y += steps
                # flicker on the 1 Hz grid, held (chunks start on the grid: ROWS is a multiple of RATE)
                n_grid = -(-n // hold)
                sigma = b * np.sqrt(np.log(4.0) / np.pi)
                flick = np.zeros((n_grid, 3))
                for i, p in enumerate(phi):
                    e = sigma * np.sqrt(1.0 - p * p) * rng.standard_normal((n_grid, 3))
                    out, _ = lfilter([1.0], [1.0, -p], e, axis=0, zi=p * gm_state[k][i][None, :])
                    gm_state[k][i] = out[-1]
                    flick += out
                y += np.repeat(flick, hold, axis=0)[:n]
                cols.update({c: y[:, j] for j, c in enumerate(names)})
            w.write_table(pa.table(cols, schema=schema), row_group_size=ROWS)
    t_end = (n_samples - 1) * dt
    manifest = {
        "format": FORMAT, "id": str(uuid.uuid4()), "unit": {"serial": "bench-allan-1", "model": "industrial_mems"},
        "site": {"latitude_deg": 40.8, "longitude_deg": 14.25, "height_m": 0.0, "table_zero_azimuth_deg": 0.0},
        "sample_rate_hz": RATE, "procedure": "allan", "options": {"duration_s": n_samples * dt, "soak": False},
        "rig": "benchmark", "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "complete": True,
        "steps": [{"index": 0, "kind": "static", "t_start": 0.0, "t_end": t_end, "mount": np.eye(3).tolist(),
                   "table_angle": 0.0, "table_rate": 0.0, "temperature_c": 25.0, "label": "allan"}],
    }
    (directory / "session.json").write_text(json.dumps(manifest, indent=1) + "\n")
    return directory


def run_worker(session_dir: Path) -> dict:
    """Run ``analyze_one("allan", session_dir)`` in a fresh process; its report (peak RSS in KiB)."""
    proc = subprocess.run([sys.executable, "-c", _WORKER, str(session_dir)], capture_output=True, text=True,
                          check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"worker failed: {proc.stderr.strip().splitlines()[-1:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def worker_peak_memory(n_samples: int, work_dir: str | Path, keep: bool = False) -> tuple[int, float]:
    """(peak RSS bytes, wall seconds) of a fresh worker process analysing an ``n_samples`` Allan session
    written under ``work_dir`` (deleted afterwards unless ``keep``); raises if the analysis failed."""
    d = write_session(int(n_samples), Path(work_dir) / f"allan-{int(n_samples)}")
    try:
        t0 = time.perf_counter()
        rep = run_worker(d)
        seconds = time.perf_counter() - t0
    finally:
        if not keep:
            shutil.rmtree(d)
    if not rep["ok"]:
        raise RuntimeError(f"allan analysis failed: {rep['error']}")
    return rep["peak_rss_kib"] * 1024, seconds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("samples", type=float, help="samples of the hold, e.g. 1e8")
    ap.add_argument("--dir", type=Path, default=None, help="work folder (default: a new temp folder)")
    ap.add_argument("--keep", action="store_true", help="keep the written session")
    args = ap.parse_args()
    n = int(args.samples)
    work = args.dir or Path(tempfile.mkdtemp(prefix="wb-allan-mem-"))
    t0 = time.perf_counter()
    d = write_session(n, work / f"allan-{n}")
    size = (d / "samples.parquet").stat().st_size
    print(f"wrote {n:.3g} samples ({n / RATE / 3600:.1f} h at {RATE:g} Hz), {size / 1e9:.2f} GB Parquet "
          f"in {time.perf_counter() - t0:.0f} s -> {d}")
    t0 = time.perf_counter()
    rep = run_worker(d)
    wall = time.perf_counter() - t0
    if not rep["ok"]:
        raise SystemExit(f"allan analysis failed: {rep['error']}")
    print(f"worker (fresh process, analyze_one('allan')): peak RSS {rep['peak_rss_kib'] / 1024:.0f} MiB "
          f"(after imports {rep['import_rss_kib'] / 1024:.0f} MiB), analysis {rep['seconds']:.0f} s, "
          f"process wall {wall:.0f} s")
    for triad, k, term in (("gyro", "g", "arw"), ("accel", "a", "vrw")):
        nb = rep["noise"][triad]
        print(f"  {triad} (SI; simulated {term} {NOISE[k][0]:.4g}, B {NOISE[k][1]:.4g}, K {NOISE[k][2]:.4g}):")
        for name in (term, "bias_instability", "rrw"):
            print(f"    {name:17s}" + "  ".join("not observed" if v is None else f"{v:.4g}" for v in nb[name]))
    if not args.keep:
        shutil.rmtree(d)


if __name__ == "__main__":
    main()
