"""Allan deviation speed: in-memory kernel vs allantools, and streaming vs in-memory.

1. Octave-tau overlapping ADEV of ``--n`` samples x 3 axes (default 1e7): the workbench (all
   axes in one call) against allantools ``oadev`` called per axis; prints both times, the
   ratio and the largest relative difference of the numbers.
2. Streaming: writes a ``--stream-n``-sample single-channel Parquet file (default 1e9, 8 GB;
   row groups of 1M), then computes its octave OADEV with
   :func:`workbench.analysis.allan_stream.stream_deviation` in a child process and reports the
   child's peak RSS and throughput, against the in-memory path on ``--memory-n`` samples
   (default min(stream-n, 1e8)) also in a child process.

3. The whole command (``--command-n`` samples x 3 axes in a Parquet file, default 0 = skip):
   ``workbench allan FILE --rate 100 --taus octave --out curves.csv`` (start-up, read, OADEV,
   intervals, fit, table, CSV) against a plain allantools script (read the same Parquet,
   ``oadev`` per axis with its default error bars, write a CSV), each in a fresh process,
   interleaved ``--repeat`` times; medians of wall time, CPU time and peak RSS, the load average;
   then the CPU of each of the command's steps (read, numba, phase and sums, intervals, fit, output)
   timed in one process, ``--repeat`` processes.
   ``--all-n``: the same with every tau (``--stat oadev --taus all``: m = 1 .. N / 4 with
   intervals; allantools given the same taus).
4. The total family (``--total-n`` samples for TOTDEV, default 1e6; ``--mtot-n`` for MTOTDEV, TTOTDEV,
   HTOTDEV, default 1e4; octave taus, one channel, in one process): CPU of the statistic against plain
   fused single-pass numba kernels of the same sums (per lag one loop over the record; per
   subsequence one loop over its reflection), and the largest relative difference.

Run: ``python benchmarks/allan_speed.py [--n 1e7] [--stream-n 1e9] [--memory-n 1e8] [--command-n 1e7]
[--all-n 1e4] [--total-n 1e6] [--mtot-n 1e4] [--dir /tmp]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

RATE = 100.0


def _plain_mdev_kernel():
    """The reference "fused single-pass" MDEV kernel: per lag and channel one loop over the record
    (allantools' recursion, no blocking, no channel interleaving)."""
    import numba

    @numba.njit(cache=False, nogil=True)
    def plain(x, lags, out):
        for k in range(lags.shape[0]):
            m = lags[k]
            for c in range(x.shape[0]):
                xc = x[c]
                v = 0.0
                for i in range(m):
                    v += xc[i + 2 * m] - 2.0 * xc[i + m] + xc[i]
                acc = v * v
                for j in range(1, xc.shape[0] - 3 * m + 1):
                    v += xc[j + 3 * m - 1] - 3.0 * xc[j + 2 * m - 1] + 3.0 * xc[j + m - 1] - xc[j - 1]
                    acc += v * v
                out[k, c] = acc

    return plain


def bench_in_memory(n: int) -> None:
    import allantools

    from workbench.analysis import allan
    from workbench.analysis.allan import deviation

    rng = np.random.default_rng(1)
    y = 1e-3 * rng.standard_normal((n, 3)) + 1e-7 * np.cumsum(rng.standard_normal((n, 3)), axis=0)
    plain = _plain_mdev_kernel()
    for kind, at_fn in (("oadev", allantools.oadev), ("mdev", allantools.mdev)):
        deviation(y[:10_000], RATE, kind)  # compile the kernels (cached on disk after the first run)
        t0, c0 = time.perf_counter(), time.process_time()
        curve = deviation(y, RATE, kind, "octave")
        t_wb, c_wb = time.perf_counter() - t0, time.process_time() - c0
        t0, c0 = time.perf_counter(), time.process_time()
        ref = [at_fn(np.ascontiguousarray(y[:, c]), RATE, "freq", curve.tau)[1] for c in range(3)]
        t_at, c_at = time.perf_counter() - t0, time.process_time() - c0
        diff = max(float(np.max(np.abs(curve.dev[:, c] / ref[c] - 1))) for c in range(3))
        print(f"octave {kind.upper()}, {n:.3g} samples x 3 axes ({len(curve.tau)} taus), in one process")
        print(f"  workbench : {t_wb:7.3f} s wall, {c_wb:7.3f} s CPU ({3 * n / c_wb / 1e6:6.1f} M samples/CPU s)")
        print(f"  allantools: {t_at:7.3f} s wall, {c_at:7.3f} s CPU (per axis)")
        line = f"  ratio allantools / workbench {c_at / c_wb:.1f}x CPU, max relative difference {diff:.2e}"
        if kind == "mdev":
            x = allan.phase(y, RATE)
            sums = np.zeros((len(curve.m), 3))
            plain(x[:, :10_000], curve.m[curve.m * 3 < 10_000], sums)  # compile
            c0 = time.process_time()
            plain(x, curve.m, sums)
            c_plain = time.process_time() - c0
            line += (f"; a plain fused single-pass kernel: {c_plain:.3f} s CPU (workbench / plain "
                     f"{c_wb / c_plain:.2f}, phase included in workbench)")
        print(line)
def _plain_total_kernels():
    """Reference "fused single-pass" kernels of the total family, per lag one loop over the record:
    totdev over an explicitly reflected copy of the phase, mtotdev / htotdev per subsequence of 3m
    points with its detrended 9m reflection written out and its m-point sums from a prefix sum
    (SP 1065 eq. 25, 27; the construction allantools loops over in Python)."""
    import numba

    @numba.njit(cache=False, nogil=True)
    def totdev(x, m):
        n = x.shape[0]
        ext = np.empty(n + 2 * m)  # x*[k] for k = -m .. n - 1 + m
        for k in range(-m, n + m):
            ext[k + m] = 2.0 * x[0] - x[-k] if k < 0 else (2.0 * x[n - 1] - x[2 * n - 2 - k] if k >= n else x[k])
        acc = 0.0
        for t in range(1, n - 1):
            d = ext[t] - 2.0 * ext[t + m] + ext[t + 2 * m]
            acc += d * d
        return acc

    @numba.njit(cache=False, nogil=True)
    def mtot(x, m, hadamard):
        three = 3 * m
        h1, h2 = three // 2, (three + 1) // 2
        dist = (0.5 * (three - 1) + 1.0) if three % 2 == 1 else 0.5 * three
        star = np.empty(9 * m)
        cs = np.empty(9 * m + 1)
        total = 0.0
        for i in range(x.shape[0] - three + 1):
            slope = (x[i + h2:i + three].mean() - x[i:i + h1].mean()) / dist
            for j in range(three):
                v = x[i + j] - slope * ((j - h1) if hadamard else j)
                star[three + j] = v
                star[three - 1 - j] = v
                star[3 * three - 1 - j] = v
            cs[0] = 0.0
            for j in range(9 * m):
                cs[j + 1] = cs[j] + star[j]
            acc = 0.0
            for j in range(6 * m):
                d = (cs[j + 3 * m] - 2.0 * cs[j + 2 * m] + cs[j + m] - (cs[j + 2 * m] - 2.0 * cs[j + m] + cs[j])) / m
                acc += d * d
            total += acc / (6.0 * m) / (6.0 if hadamard else 1.0)
        return total

    return totdev, mtot


def bench_total(n_tot: int, n_mtot: int) -> None:
    """The total family (octave taus, one channel, in one process) against the plain kernels of
    :func:`_plain_total_kernels`: CPU of :func:`workbench.analysis.stability.stability` (phase and
    normalisation included) over the CPU of the plain sums alone."""
    from workbench.analysis.stability import factors, stability, to_phase

    totdev, mtot = _plain_total_kernels()
    rng = np.random.default_rng(4)
    for stat, n in (("totdev", n_tot), ("mtotdev", n_mtot), ("ttotdev", n_mtot), ("htotdev", n_mtot)):
        y = 1e-3 * rng.standard_normal(n)
        stability(y[:1000], RATE, stat)  # load numba and the cached kernels
        x = to_phase(y, RATE, "freq")
        m = factors(len(x), "octave", RATE, stat)
        if stat == "totdev":
            totdev(x[:100], 2)
        else:
            mtot(x[:100], 2, False)
        c0 = time.process_time()
        curve = stability(y, RATE, stat, "freq", "octave")
        c_wb = time.process_time() - c0
        c0 = time.process_time()
        if stat == "totdev":
            sums = np.array([totdev(x, int(k)) for k in m])
            ref = np.sqrt(sums / (2.0 * (m / RATE) ** 2 * (len(x) - 2)))
        elif stat == "htotdev":
            yf = np.diff(x) * RATE
            k = m[m > 1]
            sums = np.array([mtot(yf, int(v), True) for v in k])
            ref = np.sqrt(sums / (len(yf) - 3 * k + 1))
        else:
            sums = np.array([mtot(x, int(v), False) for v in m])
            ref = np.sqrt(sums / (2.0 * (m / RATE) ** 2 * (len(x) - 3 * m + 1)))
            if stat == "ttotdev":
                ref = ref * (m / RATE) / np.sqrt(3.0)
        c_plain = time.process_time() - c0
        dev = curve.dev[curve.m > 1] if stat == "htotdev" else curve.dev
        diff = float(np.max(np.abs(dev / ref - 1)))
        print(f"octave {stat.upper()}, {n:.3g} samples ({len(curve.m)} taus): workbench {c_wb:.3f} s CPU, plain fused "
              f"single-pass kernel {c_plain:.3f} s CPU (workbench / plain {c_wb / c_plain:.2f}), max relative "
              f"difference {diff:.1e}")


def write_parquet(path: Path, n: int, chunk: int = 1 << 20) -> None:
    """``n`` samples of white + random-walk rate noise in column ``gx``, row groups of ``chunk``."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    rng = np.random.default_rng(2)
    walk = 0.0
    schema = pa.schema([("gx", pa.float64())])
    with pq.ParquetWriter(path, schema, compression="none") as w:
        for start in range(0, n, chunk):
            k = min(chunk, n - start)
            steps = 1e-7 * rng.standard_normal(k)
            y = 1e-3 * rng.standard_normal(k) + walk + np.cumsum(steps)
            walk = float(walk + steps.sum())
            w.write_table(pa.table({"gx": y}, schema=schema), row_group_size=chunk)


_CHILD = """
import json, resource, sys, time
import numpy as np
mode, path, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
from workbench.analysis.allan import deviation
from workbench.analysis.allan_stream import stream_deviation
deviation(np.random.default_rng(0).standard_normal(10_000), 100.0)
t0 = time.perf_counter()
if mode == "stream":
    c = stream_deviation(path, ["gx"], 100.0, "oadev", "octave", tmp_dir=sys.argv[4])
else:
    import pyarrow.parquet as pq
    y = pq.read_table(path, columns=["gx"]).column("gx").to_numpy()[:n]
    c = deviation(y, 100.0, "oadev", "octave")
dt = time.perf_counter() - t0
print(json.dumps({"s": dt, "n": c.n_samples, "rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "dev": c.dev[:, 0].tolist()}))
"""


def _child(mode: str, path: Path, n: int, tmp: Path) -> dict:
    res = subprocess.run([sys.executable, "-c", _CHILD, mode, str(path), str(n), str(tmp)], capture_output=True,
                         text=True, check=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


def bench_stream(n: int, memory_n: int, directory: Path) -> None:
    with tempfile.TemporaryDirectory(dir=directory, prefix="allan-bench-") as tmp:
        big, small = Path(tmp) / "big.parquet", Path(tmp) / "small.parquet"
        t0 = time.perf_counter()
        write_parquet(big, n)
        print(f"streaming: wrote {n:.3g} samples ({big.stat().st_size / 1e9:.2f} GB) in {time.perf_counter() - t0:.0f} s")
        s = _child("stream", big, n, Path(tmp))
        if memory_n != n:
            write_parquet(small, memory_n)
        else:
            small = big
        m = _child("memory", small, memory_n, Path(tmp))
        sm = s if small == big else _child("stream", small, memory_n, Path(tmp))
        diff = float(np.max(np.abs(np.array(sm["dev"]) / np.array(m["dev"]) - 1)))
        print(f"  stream {n:.3g}: {s['s']:7.1f} s, {n / s['s'] / 1e6:6.1f} M samples/s, peak RSS {s['rss_mb']:.0f} MB")
        print(f"  memory {memory_n:.3g}: {m['s']:7.1f} s, {memory_n / m['s'] / 1e6:6.1f} M samples/s, "
              f"peak RSS {m['rss_mb']:.0f} MB (incl. reading the file)")
        print(f"  stream {memory_n:.3g}: {sm['s']:7.1f} s, peak RSS {sm['rss_mb']:.0f} MB, "
              f"max relative difference to in-memory {diff:.2e}")
        print(f"  throughput ratio in-memory / streaming: {(memory_n / m['s']) / (n / s['s']):.2f}")


_ALLANTOOLS_SCRIPT = """
import sys
import allantools, numpy as np, pandas as pd
df = pd.read_parquet(sys.argv[1])
if sys.argv[3] == "all":  # every m up to Stable32's stop ratio 4, the grid of ``workbench allan --taus all``
    taus = np.arange(1, len(df) // 4 + 1) / 100.0
else:
    taus = sys.argv[3]
rows = []
for c in df.columns:
    t, d, e, n = allantools.oadev(df[c].to_numpy(), 100.0, "freq", taus)
    rows += [(c, *v) for v in zip(t, d, e, n)]
pd.DataFrame(rows, columns=["column", "tau", "dev", "err", "n"]).to_csv(sys.argv[2], index=False)
"""

_TIMED = """
import resource, subprocess, sys, time
t0 = time.perf_counter()
subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL)
r = resource.getrusage(resource.RUSAGE_CHILDREN)
print(time.perf_counter() - t0, r.ru_maxrss / 1024, r.ru_utime + r.ru_stime)
"""


_STEPS = """
import json, sys, time
laps, t = [], [time.process_time()]
def lap(name):
    c = time.process_time(); laps.append((name, c - t[0])); t[0] = c
from pathlib import Path
import numpy as np; lap("numpy")
from workbench.cli import main; lap("typer, rich, workbench.cli")
from workbench.cli.allan_record import load_record, quantity_of
from workbench.analysis import allan, allan_ci, allan_fit
from workbench.cli.allan_csv import CURVE_COLUMNS, curve_rows, write_csv
from workbench.cli.allan_tables import print_terms
lap("the command's modules")
import pyarrow.parquet as pq; pq.ParquetFile(sys.argv[1]).metadata.num_rows; lap("pyarrow, size check")
y, fs, cols, label = load_record(Path(sys.argv[1]), None, 100.0); lap("Parquet read")
if y.size > allan.COMPILED_WORK / 20:
    from workbench.analysis import allan_kernels
    allan_kernels.column_sums(np.zeros((2, 3))); lap("numba, first cached kernel")
inner = {}
def timed(module, name, step):  # the calls of analyze_record, timed where it makes them
    orig = getattr(module, name)
    def call(*a, **k):
        c = time.process_time(); r = orig(*a, **k); inner[step] = inner.get(step, 0.0) + time.process_time() - c
        return r
    setattr(module, name, call)
for module, name, step in ((allan, "segment_deviation", "phase, OADEV sums"), (allan_ci, "confidence", "intervals"),
                           (allan_fit, "fit_terms", "IEEE 952 fit")):
    timed(module, name, step)
an = allan_fit.analyze_record(y, fs, cols, quantity_of(cols), "octave", "error", label, overwrite=True)
c = time.process_time()
laps += list(inner.items())
laps.append(("checks, rate mean square", c - t[0] - sum(inner.values()))); t[0] = c
print_terms(an); write_csv(Path(sys.argv[2]), CURVE_COLUMNS, curve_rows(an)); lap("table, CSV")
sys.stdout.flush()
print("STEPS " + json.dumps(laps))
"""


def _steps(path: Path, out_csv: Path, repeat: int) -> list[tuple[str, list[float]]]:
    """CPU (s) of each step of the octave command (:data:`_STEPS`: the command's calls, those inside
    ``analyze_record`` timed where it makes them, in one fresh process), ``repeat`` processes; (step, CPU per run)."""
    runs = []
    for _ in range(repeat):
        res = subprocess.run([sys.executable, "-c", _STEPS, str(path), str(out_csv)], capture_output=True, text=True,
                             check=True)
        runs.append(json.loads(res.stdout.rsplit("STEPS ", 1)[1]))
    return [(name, [r[k][1] for r in runs]) for k, (name, _) in enumerate(runs[0])]


def _timed(cmd: list[str]) -> tuple[float, float, float]:
    """Wall time (s), peak RSS (MB) and CPU time (s) of ``cmd`` in a fresh process."""
    out = subprocess.run([sys.executable, "-c", _TIMED, *cmd], capture_output=True, text=True, check=True)
    wall, rss, cpu = out.stdout.split()
    return float(wall), float(rss), float(cpu)


def bench_command(n: int, taus: str, repeat: int, directory: Path) -> None:
    """The whole ``workbench allan`` command against a plain allantools script on one Parquet file.

    ``taus`` ``octave``: the default command (OADEV, intervals with noise identification, IEEE 952
    fit, terms table, curves CSV); ``all``: ``--stat oadev --taus all`` (every m up to N / 4, with
    intervals), allantools given the same taus.
    """
    import pandas as pd

    with tempfile.TemporaryDirectory(dir=directory, prefix="allan-cmd-") as tmp:
        path = Path(tmp) / "rec.parquet"
        rng = np.random.default_rng(3)
        pd.DataFrame(1e-3 * rng.standard_normal((n, 3)), columns=["gx", "gy", "gz"]).to_parquet(path)
        size_mb = path.stat().st_size / 1e6
        wb = [sys.executable, "-m", "workbench", "allan", str(path), "--rate", "100", "--taus", taus,
              "--out", str(Path(tmp) / "wb.csv")] + (["--stat", "oadev"] if taus == "all" else [])
        at = [sys.executable, "-c", _ALLANTOOLS_SCRIPT, str(path), str(Path(tmp) / "at.csv"), taus]
        _timed(wb)  # compile / warm the caches once
        res: dict[str, list] = {"workbench": [], "allantools": []}
        load = [os.getloadavg()[0]]
        for _ in range(repeat):
            res["workbench"].append(_timed(wb))
            res["allantools"].append(_timed(at))
            load.append(os.getloadavg()[0])
        wb_csv = pd.read_csv(Path(tmp) / "wb.csv")
        wb_dev = wb_csv["dev" if "dev" in wb_csv else "adev"].to_numpy()
        at_dev = pd.read_csv(Path(tmp) / "at.csv")["dev"].to_numpy()
        diff = float(np.max(np.abs(wb_dev / at_dev - 1))) if wb_dev.shape == at_dev.shape else float("nan")
        print(f"whole command, {n:.3g} samples x 3 axes, {taus} taus ({len(wb_dev) // 3} per axis, "
              f"{size_mb:.0f} MB Parquet), medians of {repeat} interleaved runs, load average "
              f"{min(load):.1f}-{max(load):.1f} on {os.cpu_count()} CPUs:")
        med = {k: np.median(np.array(v), axis=0) for k, v in res.items()}
        for k, (wall, rss, cpu) in med.items():
            print(f"  {k:10s}: {wall:7.2f} s wall, {cpu:7.2f} s CPU, peak RSS {rss:6.0f} MB")
        print(f"  ratio allantools / workbench: {med['allantools'][0] / med['workbench'][0]:.2f}x wall, "
              f"{med['allantools'][2] / med['workbench'][2]:.2f}x CPU (the CPU ratio is the one to read on a "
              f"loaded machine); max relative difference of the deviations {diff:.1e}")
        if taus == "octave":
            load0 = os.getloadavg()[0]
            steps = _steps(path, Path(tmp) / "steps.csv", repeat)
            total = sum(float(np.median(v)) for _, v in steps)
            print(f"  where the workbench's CPU goes (the command's calls timed in one process, medians of {repeat}, "
                  f"load {load0:.1f}-{os.getloadavg()[0]:.1f}; typer's option parsing not included):")
            for name, v in steps:
                print(f"    {name:28s} {np.median(v):6.3f} s ({min(v):.3f}-{max(v):.3f})")
            print(f"    {'total':28s} {total:6.3f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=float, default=1e7, help="samples per axis for the allantools comparison")
    ap.add_argument("--stream-n", type=float, default=1e9, help="samples of the streamed Parquet file (0: skip)")
    ap.add_argument("--memory-n", type=float, default=None, help="samples of the in-memory comparison run")
    ap.add_argument("--dir", type=Path, default=Path(tempfile.gettempdir()), help="folder for the temporary files")
    ap.add_argument("--command-n", type=float, default=0, help="samples per axis of the whole-command comparison, "
                                                               "octave taus (0: skip)")
    ap.add_argument("--all-n", type=float, default=0, help="samples per axis of the whole-command comparison, "
                                                           "every tau (0: skip)")
    ap.add_argument("--total-n", type=float, default=1e6, help="samples of the TOTDEV comparison with plain kernels "
                                                             "(0: skip the total family)")
    ap.add_argument("--mtot-n", type=float, default=1e4, help="samples of the MTOTDEV / TTOTDEV / HTOTDEV comparison")
    ap.add_argument("--repeat", type=int, default=3, help="interleaved repetitions of the whole-command comparison")
    args = ap.parse_args()
    if args.n > 0:
        bench_in_memory(int(args.n))
    if args.total_n > 0:
        bench_total(int(args.total_n), int(args.mtot_n))
    if args.command_n > 0:
        bench_command(int(args.command_n), "octave", args.repeat, args.dir)
    if args.all_n > 0:
        bench_command(int(args.all_n), "all", args.repeat, args.dir)
    if args.stream_n > 0:
        bench_stream(int(args.stream_n), int(args.memory_n or min(args.stream_n, 1e8)), args.dir)


if __name__ == "__main__":
    main()
