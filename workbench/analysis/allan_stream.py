"""Allan and Hadamard deviations of a Parquet record too large for memory.

Three sequential passes, memory bounded by the chunk and window sizes (not the record):

1. read the rate columns row group by row group (pyarrow ``iter_batches``): count, column
   sums for the mean, NaN check (a streamed record must be gap-free: the error names the row);
2. integrate to phase chunk by chunk (the running sum carried across chunks, the same
   operations as :func:`workbench.analysis.allan.phase`) into one temporary raw float64
   file per channel;
3. sweep the difference index in blocks of ``block`` points: lags with ``order * m <= window``
   are summed from one contiguous read of the block plus its tail, larger lags from
   reads of ``block`` points at offsets m, 2m (, 3m) (each offset read once per block: the 2m
   of one octave lag is the m of the next; offset 0 is the start of the shared read), summed
   by the same compiled kernel as in memory (:func:`workbench.analysis.allan._block_sum`).
   Read buffers are reused, so the sweep allocates nothing per block.

The results equal the in-memory :func:`workbench.analysis.allan.deviation` (the sums are only
grouped differently: relative differences ~1e-13). The modified Allan deviation's running
inner sum is not streamed; use the in-memory path for ``mdev``.

Public: :func:`stream_deviation`.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from workbench.analysis import allan
from workbench.analysis.allan import DeviationCurve
from workbench.errors import AnalysisError

STREAM_KINDS = ("oadev", "ohdev")
_SUB = 1 << 16  # differences per compiled partial sum of the long lags (keeps the summation accurate)


def _batches(pf: pq.ParquetFile, columns: list[str], rows: int):
    for batch in pf.iter_batches(batch_size=rows, columns=columns):
        yield np.column_stack([batch.column(c).to_numpy(zero_copy_only=False).astype(float, copy=False)
                               for c in columns])


def _scan(pf: pq.ParquetFile, columns: list[str], rows: int, source: str) -> tuple[int, np.ndarray]:
    """Pass 1: sample count and column sums; raises on the first non-finite value."""
    n, sums = 0, np.zeros(len(columns))
    for y in _batches(pf, columns, rows):
        if not np.isfinite(y.sum()):
            bad = ~np.isfinite(y)
            row, col = np.argwhere(bad)[0]
            raise AnalysisError(f"{source}: column {columns[col]}: NaN or infinite value at row {n + row} "
                                "(streaming needs a gap-free record; load it in memory for a gap policy)")
        sums += allan.column_sums(np.ascontiguousarray(y))
        n += len(y)
    return n, sums


def _read(fh, start: int, count: int, pool: list[np.ndarray]) -> np.ndarray:
    """x[start:start+count] of a raw float64 file, into a buffer reused from ``pool`` (no page faults)."""
    i = next((i for i, b in enumerate(pool) if len(b) >= count), None)
    buf = np.empty(count) if i is None else pool.pop(i)
    fh.seek(8 * start)
    fh.readinto(memoryview(buf[:count]).cast("B"))
    return buf[:count]


def stream_deviation(path: str | Path, columns: list[str] | tuple[str, ...], rate: float, kind: str = "oadev",
                     taus: str | np.ndarray = "octave", rows: int = 1 << 20, block: int = 1 << 22,
                     window: int = 1 << 22, tmp_dir: str | Path | None = None) -> DeviationCurve:
    """Deviation ``kind`` (oadev | ohdev) of rate ``columns`` of a Parquet file at ``rate`` Hz.

    ``rows`` samples are read per batch, ``block`` differences summed per sweep step and lags
    up to ``window / order`` served from one contiguous read; the phase (8 bytes per sample
    and channel) is held in temporary files under ``tmp_dir`` (default: the system's).
    Peak memory is about ``8 * (3 * rows * C + window + (2 * order + 2) * block)`` bytes (order 2 for
    oadev, 3 for ohdev): ~0.3 GB with the defaults, whatever the record length.
    """
    path = Path(path)
    source = str(path)
    if kind not in STREAM_KINDS:
        raise AnalysisError(f"{source}: streaming supports {', '.join(STREAM_KINDS)}, not {kind}")
    try:
        pf = pq.ParquetFile(path, pre_buffer=False)  # pre-buffering holds whole row groups twice
    except Exception as exc:  # pyarrow raises several types for unreadable files
        raise AnalysisError(f"{source}: cannot read Parquet ({type(exc).__name__}: {str(exc)[:120]})") from None
    missing = [c for c in columns if c not in pf.schema_arrow.names]
    if missing:
        raise AnalysisError(f"{source}: no column(s) {', '.join(missing)} (has {', '.join(pf.schema_arrow.names)})")
    columns = list(columns)
    n, sums = _scan(pf, columns, rows, source)
    if n < allan.MIN_SAMPLES:
        raise AnalysisError(f"{source}: {n} samples; Allan statistics need at least {allan.MIN_SAMPLES}")
    n_phase = n + 1
    m = allan.averaging_factors(n_phase, taus, rate, kind)
    order = allan.ORDER[kind]
    counts = allan._n_terms(kind, n_phase, m)
    with tempfile.TemporaryDirectory(dir=tmp_dir, prefix="allan-stream-") as tmp:
        files = [Path(tmp) / f"phase{c}.f64" for c in range(len(columns))]
        _write_phase(pf, columns, rows, rate, sums / n, files)
        out = np.zeros((len(m), len(columns)))
        for c, f in enumerate(files):
            with open(f, "rb") as fh:
                out[:, c] = _sweep(fh, m, counts, order, n_phase, block, window)
    return DeviationCurve(kind, m / rate, m, allan.normalise(kind, out, counts, m, rate), counts, float(rate), n,
                          tuple(columns))


def _write_phase(pf, columns, rows, rate, mean, files) -> None:
    """Pass 2: phase of every channel into its raw float64 file (x_0 = 0 first)."""
    run = np.zeros(len(columns))
    handles = [open(f, "wb") for f in files]
    try:
        for fh in handles:
            np.zeros(1).tofile(fh)
        for y in _batches(pf, columns, rows):
            x = np.empty((len(columns), len(y)))
            allan._integrate(np.ascontiguousarray(y), mean, 1.0 / float(rate), run, x)
            for fh, xc in zip(handles, x):
                xc.tofile(fh)
    finally:
        for fh in handles:
            fh.close()


def _sweep(fh, m: np.ndarray, counts: np.ndarray, order: int, n_phase: int, block: int, window: int) -> np.ndarray:
    """Pass 3 for one channel: sums of squared differences (K,) at factors ``m`` (ascending)."""
    out = np.zeros(len(m))
    small = order * m <= window
    ms, cs = m[small], counts[small]
    big = np.flatnonzero(~small)
    pool: list[np.ndarray] = []
    for start in range(0, int(counts.max()), block):
        x = _read(fh, start, min(block + (int(order * ms.max()) if len(ms) else 0), n_phase - start), pool)
        if len(ms):
            part = np.zeros((len(ms), 1))
            allan._diff_sums(x[None, :], ms, order, np.zeros_like(ms), np.clip(cs - start, 0, block).astype(np.int64),
                             part)
            out[small] += part[:, 0]
        # offset -> x[start + offset:][:block]; the 2m of one octave lag is the m of the next
        reads: dict[int, np.ndarray] = {0: x[:block]}
        for k in big:
            count = int(min(counts[k] - start, block))
            if count <= 0:
                continue
            for off in (p * int(m[k]) for p in range(1, order + 1)):
                if off not in reads:
                    reads[off] = _read(fh, start + off, min(block, n_phase - start - off), pool)
            w = [reads[p * int(m[k])] for p in range(order + 1)] + [reads[0]] * (3 - order)
            for s0 in range(0, count, _SUB):
                s1 = min(s0 + _SUB, count)
                out[k] += allan._block_sum(w[0][s0:s1], w[1][s0:s1], w[2][s0:s1], w[3][s0:s1], order)
            for off in [o for o in reads if 0 < o <= m[k]]:
                pool.append(reads.pop(off).base)
        pool.extend(r.base for o, r in reads.items() if o > 0)
        pool.append(x.base)
    return out
