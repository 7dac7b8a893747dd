"""Allan and Hadamard deviations of a record too large for memory, streamed in batches.

The record comes from a factory of batch iterators (each call restarts it: consecutive (n, C)
blocks of SI rate samples), e.g. a Parquet file's row groups (:func:`stream_deviation`) or one
step of a lazily loaded session (``lambda: session.stream(columns, step, rows)``). Three
sequential passes, memory bounded by the batch, block and window sizes (not the record):

1. count, column sums for the mean, NaN check (a streamed record must be gap-free: the error
   names the row), and the magnitude check of :func:`workbench.analysis.allan.prepare_rate_data`
   on the first 100 000 samples (as in memory);
2. integrate to phase batch by batch (the running sum carried across batches, the same
   operations as :func:`workbench.analysis.allan.phase`) into one temporary raw float64
   file per channel; optionally keep the phase decimated by every averaging factor m,
   ``x[::m][:keep]``, for noise identification (:func:`workbench.analysis.allan_ci.identify_decimated`);
3. sweep the difference index in blocks of ``block`` points: lags with ``order * m <= window``
   are summed from one contiguous read of the block plus its tail, larger lags from
   reads of ``block`` points at offsets m, 2m (, 3m) (each offset read once per block: the 2m
   of one octave lag is the m of the next; offset 0 is the start of the shared read), summed
   by the same compiled kernel as in memory (:func:`workbench.analysis.allan_kernels.block_sum`).
   Read buffers are reused, so the sweep allocates nothing per block.

The results equal the in-memory :func:`workbench.analysis.allan.deviation` (the sums are only
grouped differently: relative differences ~1e-13). The modified Allan deviation's running
inner sum is not streamed; use the in-memory path for ``mdev``.

Public: :func:`stream_deviation_from`, :func:`stream_deviation`, :class:`StreamedDeviation`.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from workbench.analysis import allan
from workbench.analysis import allan_kernels as kern
from workbench.analysis.allan import DeviationCurve
from workbench.errors import AnalysisError

STREAM_KINDS = ("oadev", "ohdev")
_SUB = 1 << 16  # differences per compiled partial sum of the long lags (keeps the summation accurate)
_HEAD = 100_000  # samples of the magnitude check (the in-memory path checks the same first samples)

Batches = Callable[[], Iterator[np.ndarray]]


@dataclass(frozen=True)
class StreamedDeviation:
    """A streamed deviation curve and the decimated phase kept for noise identification.

    ``decimated[k]`` (C, min(ceil(L / m_k), keep)) is the phase ``x[:, ::m_k][:, :keep]`` (rad |
    m/s; L = N + 1 points) at the curve's factor m_k; empty tuple when ``keep`` was 0. ``mean`` (C,)
    the rate's mean (rad/s | m/s^2), removed from the phase.
    """

    curve: DeviationCurve
    decimated: tuple[np.ndarray, ...]
    mean: np.ndarray


def _batches(pf: pq.ParquetFile, columns: list[str], rows: int):
    for batch in pf.iter_batches(batch_size=rows, columns=columns):
        yield np.column_stack([batch.column(c).to_numpy(zero_copy_only=False).astype(float, copy=False)
                               for c in columns])


def _scan(batches: Batches, columns: list[str], source: str, quantity: str | None) -> tuple[int, np.ndarray]:
    """Pass 1: sample count and column sums; raises on the first non-finite value or a wrong unit."""
    n, sums, head = 0, np.zeros(len(columns)), []
    for y in batches():
        if y.ndim != 2 or y.shape[1] != len(columns):
            raise AnalysisError(f"{source}: a batch of shape {y.shape} does not match columns {', '.join(columns)}")
        if not np.isfinite(y.sum()):
            bad = ~np.isfinite(y)
            row, col = np.argwhere(bad)[0]
            raise AnalysisError(f"{source}: column {columns[col]}: NaN or infinite value at row {n + row} "
                                "(streaming needs a gap-free record; load it in memory for a gap policy)")
        if quantity is not None and n < _HEAD:
            head.append(np.array(y[:_HEAD - n]))
        sums += kern.column_sums(np.ascontiguousarray(y))
        n += len(y)
    if quantity is not None and head:
        allan._check_magnitude(np.concatenate(head), columns, source, quantity)
    return n, sums


def _read(fh, start: int, count: int, pool: list[np.ndarray]) -> np.ndarray:
    """x[start:start+count] of a raw float64 file, into a buffer reused from ``pool`` (no page faults)."""
    i = next((i for i, b in enumerate(pool) if len(b) >= count), None)
    buf = np.empty(count) if i is None else pool.pop(i)
    fh.seek(8 * start)
    fh.readinto(memoryview(buf[:count]).cast("B"))
    return buf[:count]


def stream_deviation_from(batches: Batches, columns: list[str] | tuple[str, ...], rate: float,
                          kind: str = "oadev", taus: str | np.ndarray = "octave", block: int = 1 << 22,
                          window: int = 1 << 22, tmp_dir: str | Path | None = None, source: str = "stream",
                          quantity: str | None = None, keep: int = 0) -> StreamedDeviation:
    """Deviation ``kind`` (oadev | ohdev) of a record of rate ``columns`` at ``rate`` Hz, streamed.

    ``batches()`` returns a fresh iterator over consecutive (n, C) blocks of the record (SI:
    rad/s or m/s^2; it is called twice); ``quantity`` (``"gyro"`` | ``"accel"``) enables the
    magnitude check; ``keep`` decimated phase points are kept per factor (see
    :class:`StreamedDeviation`; ``keep * C * 8`` bytes per tau at most). ``block`` differences
    are summed per sweep step and lags up to ``window / order`` served from one contiguous read;
    the phase (8 bytes per sample and channel) is held in temporary files under ``tmp_dir``
    (default: the system's). Peak memory is about ``8 * (3 * rows * C + window + (2 * order + 2)
    * block)`` bytes for batches of ``rows`` samples (order 2 for oadev, 3 for ohdev): ~0.3 GB
    with the defaults and 1 M-row batches, whatever the record length.
    """
    if kind not in STREAM_KINDS:
        raise AnalysisError(f"{source}: streaming supports {', '.join(STREAM_KINDS)}, not {kind}")
    columns = list(columns)
    n, sums = _scan(batches, columns, source, quantity)
    if n < allan.MIN_SAMPLES:
        raise AnalysisError(f"{source}: {n} samples; Allan statistics need at least {allan.MIN_SAMPLES}")
    n_phase = n + 1
    m = allan.averaging_factors(n_phase, taus, rate, kind)
    if len(m) == 0:
        raise AnalysisError(f"{source}: no averaging time fits {n} samples for {kind}")
    order = allan.ORDER[kind]
    counts = allan._n_terms(kind, n_phase, m)
    with tempfile.TemporaryDirectory(dir=tmp_dir, prefix="allan-stream-") as tmp:
        files = [Path(tmp) / f"phase{c}.f64" for c in range(len(columns))]
        decimated = _write_phase(batches, rate, sums / n, files, m, keep, n_phase)
        out = np.zeros((len(m), len(columns)))
        for c, f in enumerate(files):
            with open(f, "rb") as fh:
                out[:, c] = _sweep(fh, m, counts, order, n_phase, block, window)
    curve = DeviationCurve(kind, m / rate, m, allan.normalise(kind, out, counts, m, rate), counts, float(rate), n,
                           tuple(columns))
    return StreamedDeviation(curve, decimated, sums / n)


def parquet_batches(path: str | Path, columns: list[str] | tuple[str, ...], rows: int = 1 << 20) -> Batches:
    """A factory of iterators over (rows, C) float blocks of ``columns`` of a Parquet file."""
    path = Path(path)
    try:
        pf = pq.ParquetFile(path, pre_buffer=False)  # pre-buffering holds whole row groups twice
    except Exception as exc:  # pyarrow raises several types for unreadable files
        raise AnalysisError(f"{path}: cannot read Parquet ({type(exc).__name__}: {str(exc)[:120]})") from None
    missing = [c for c in columns if c not in pf.schema_arrow.names]
    if missing:
        raise AnalysisError(f"{path}: no column(s) {', '.join(missing)} (has {', '.join(pf.schema_arrow.names)})")
    return lambda: _batches(pf, list(columns), rows)


def stream_deviation(path: str | Path, columns: list[str] | tuple[str, ...], rate: float, kind: str = "oadev",
                     taus: str | np.ndarray = "octave", rows: int = 1 << 20, block: int = 1 << 22,
                     window: int = 1 << 22, tmp_dir: str | Path | None = None) -> DeviationCurve:
    """Deviation ``kind`` (oadev | ohdev) of rate ``columns`` of a Parquet file at ``rate`` Hz.

    :func:`stream_deviation_from` over the file's batches of ``rows`` rows (~0.3 GB peak with
    the defaults, whatever the file size).
    """
    return stream_deviation_from(parquet_batches(path, columns, rows), columns, rate, kind, taus, block, window,
                                 tmp_dir, str(path)).curve


def _write_phase(batches: Batches, rate: float, mean: np.ndarray, files: list[Path], m: np.ndarray, keep: int,
                 n_phase: int) -> tuple[np.ndarray, ...]:
    """Pass 2: phase of every channel into its raw float64 file (x_0 = 0 first); returns the
    decimated phase x[:, ::m_k][:, :keep] per factor (empty tuple when ``keep`` is 0)."""
    n_ch = len(files)
    run = np.zeros(n_ch)
    dec = tuple(np.zeros((n_ch, min(keep, (n_phase - 1) // int(mk) + 1))) for mk in m) if keep > 0 else ()
    g0 = 1  # phase index of the batch's first point (x_0 = 0 is already in place)
    handles = [open(f, "wb") for f in files]
    try:
        for fh in handles:
            np.zeros(1).tofile(fh)
        for y in batches():
            if not len(y):
                continue
            x = np.empty((n_ch, len(y)))
            kern.integrate(np.ascontiguousarray(y), mean, 1.0 / float(rate), run, x)
            for fh, xc in zip(handles, x):
                xc.tofile(fh)
            g1 = g0 + len(y)
            for mk, z in zip(m.tolist(), dec):
                j0, j1 = -(-g0 // mk), min(z.shape[1], -(-g1 // mk))  # multiples of m in [g0, g1)
                if j1 > j0:
                    z[:, j0:j1] = x[:, j0 * mk - g0:(j1 - 1) * mk - g0 + 1:mk]
            g0 = g1
    finally:
        for fh in handles:
            fh.close()
    return dec


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
            kern.diff_sums(x[None, :], ms, order, np.zeros_like(ms), np.clip(cs - start, 0, block).astype(np.int64),
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
                out[k] += kern.block_sum(w[0][s0:s1], w[1][s0:s1], w[2][s0:s1], w[3][s0:s1], order)
            for off in [o for o in reads if 0 < o <= m[k]]:
                pool.append(reads.pop(off).base)
        pool.extend(r.base for o, r in reads.items() if o > 0)
        pool.append(x.base)
    return out
