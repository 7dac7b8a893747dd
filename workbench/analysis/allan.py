"""Overlapping Allan, modified Allan and overlapping Hadamard deviations of rate data.

Rate samples ``y`` (N, C) (gyro rad/s, accel m/s^2; all axes at once) at a constant rate are
integrated once into a phase ``x`` (angle rad / velocity m/s) exactly as allantools does
(``x_0 = 0``, ``x_k = dt * cumsum(y - mean(y))``, so ``L = N + 1`` phase points), and every
deviation is a sum of squared finite differences of ``x`` at lag ``m`` (tau = m dt):

* overlapping ADEV  sigma^2 = sum_i (x[i+2m] - 2 x[i+m] + x[i])^2 / (2 tau^2 (L - 2m))
* overlapping HDEV  sigma^2 = sum_i (x[i+3m] - 3 x[i+2m] + 3 x[i+m] - x[i])^2 / (6 tau^2 (L - 3m))
* modified ADEV     sigma^2 = sum_j (sum_{i=j}^{j+m-1} x[i+2m] - 2x[i+m] + x[i])^2 / (2 m^2 tau^2 (L - 3m + 1))

(NIST SP 1065 eq. 11, 18, 14.) Short records (up to :data:`COMPILED_WORK` squared differences
in all) are summed with numpy, one reused buffer per lag; longer ones, and every MDEV, by the
compiled kernels of :mod:`workbench.analysis.allan_kernels` (numba: cache-sized blocks, all lags
per block, no temporaries the size of the record), whose ~0.4 s start-up only they repay. Both
equal allantools' ``oadev``/``ohdev``/``mdev`` (tested to a relative 1e-9).

Public: :func:`deviation`, :func:`segment_deviation`, :func:`averaging_factors`, :func:`phase`, :func:`rate_buffer`,
:func:`prepare_rate_data`, :func:`column_median`, :class:`DeviationCurve`, :data:`KINDS`.
References: thesis (shared/seeds/000_...) sec. 1.2 (Allan variance analysis of tables 1.1-4.1);
IEEE Std 952-1997 Annex C; NIST SP 1065.
"""

from __future__ import annotations

import mmap
import re
from dataclasses import dataclass

import numpy as np

from workbench.errors import AnalysisError

KINDS = ("oadev", "mdev", "ohdev")
ORDER = {"oadev": 2, "ohdev": 3, "mdev": 3}  # lag multiples a deviation spans
MIN_SAMPLES = 100
GAP_POLICIES = ("error", "longest", "split")
COMPILED_WORK = 4e8  # squared differences (lags x channels x points) above which numba's start-up pays
POPULATE_BYTES = 1 << 26  # rate buffers from this size are mapped populated (:func:`rate_buffer`)


@dataclass(frozen=True)
class DeviationCurve:
    """A deviation versus averaging time, one column per input channel.

    ``tau`` (K,) s; ``m`` (K,) averaging factors (tau = m / rate); ``dev`` (K, C) in the input's
    rate unit (rad/s or m/s^2); ``n`` (K,) number of squared differences summed (pooled over
    segments); ``n_samples`` rate samples used; ``kind`` one of :data:`KINDS`.
    """

    kind: str
    tau: np.ndarray
    m: np.ndarray
    dev: np.ndarray
    n: np.ndarray
    rate: float
    n_samples: int
    columns: tuple[str, ...]

    @property
    def avar(self) -> np.ndarray:
        """The variance (dev squared), (K, C)."""
        return self.dev ** 2


# -- tau grids ----------------------------------------------------------------------------

def averaging_factors(n_phase: int, taus: str | np.ndarray, rate: float, kind: str = "oadev") -> np.ndarray:
    """Averaging factors m (int64, sorted, unique) for a record of ``n_phase`` phase points.

    ``taus``: ``"octave"`` (1, 2, 4, ... as allantools), ``"decade"`` (1, 2, 4, 10, 20, 40, ...
    as allantools / Stable32), ``"<k>-per-decade"`` (k log-spaced points per decade), or an
    array of taus in s (rounded to multiples of 1/rate). Factors leaving fewer than two
    differences for ``kind`` are dropped, as allantools does.
    """
    if isinstance(taus, str):
        if taus == "octave":
            top = int(np.floor(np.log2(n_phase)))
            tau_s = np.logspace(0, top, top + 1, base=2.0) / rate
        elif taus == "decade":
            top = int(np.floor(np.log10(n_phase)))
            tau_s = np.array([f * 10.0 ** k / rate for k in range(top + 1) for f in (1.0, 2.0, 4.0)])
        else:
            match = re.fullmatch(r"(\d+)-per-decade", taus)
            if not match or int(match.group(1)) < 1:
                raise AnalysisError(f"taus {taus!r}: expected octave, decade or <k>-per-decade (e.g. 10-per-decade)")
            per = int(match.group(1))
            top = np.log10(n_phase)
            tau_s = np.logspace(0, top, int(np.ceil(per * top)) + 1) / rate
    else:
        try:
            tau_s = np.asarray(taus, float).ravel()
        except (TypeError, ValueError):  # -o taus='[1, "a"]' or a mapping
            raise AnalysisError(f"taus {taus!r}: expected octave, decade, <k>-per-decade or a list of taus in s") from None
    m = np.round(tau_s * rate)
    m = np.sort(m[(m > 0) & (m < n_phase)]).astype(np.int64)
    m = m[np.concatenate(([True], m[1:] != m[:-1]))[:len(m)]]  # unique (np.unique imports numpy.ma, ~40 ms)
    n = _n_terms(kind, n_phase, m)
    return m[n > 1]


def _n_terms(kind: str, n_phase: int, m: np.ndarray) -> np.ndarray:
    """Number of squared differences the estimator sums at each m."""
    return n_phase - ORDER[kind] * m + (1 if kind == "mdev" else 0)


# -- input checks -------------------------------------------------------------------------

def prepare_rate_data(y: np.ndarray, columns: tuple[str, ...] | list[str], source: str = "data",
                      gap_policy: str = "error", quantity: str | None = None) -> tuple[list[np.ndarray], list[str]]:
    """Check rate samples and cut them into NaN-free segments according to ``gap_policy``.

    ``y`` (N, C) SI rate samples. Non-finite samples are gaps: ``"error"`` raises naming the
    column and rows, ``"longest"`` keeps the longest gap-free run, ``"split"`` keeps every run
    (deviations then pool the differences of all runs; none spans a gap). ``quantity``
    (``"gyro"``/``"accel"``) enables the plausibility check of magnitudes (wrong declared unit).
    Returns the list of (n_k, C) segments and warnings.
    """
    y = np.asarray(y, float)
    if y.ndim == 1:
        y = y[:, None]
    if y.ndim != 2 or y.shape[1] != len(columns):
        raise AnalysisError(f"{source}: samples of shape {y.shape} do not match columns {', '.join(columns)}")
    if gap_policy not in GAP_POLICIES:
        raise AnalysisError(f"{source}: gap policy {gap_policy!r} is not one of {', '.join(GAP_POLICIES)}")
    bad_rows = np.zeros(len(y), bool) if np.isfinite(y.sum()) else ~np.all(np.isfinite(y), axis=1)
    warnings: list[str] = []
    if bad_rows.any():
        runs = _runs(bad_rows)
        col = columns[int(np.argmax(~np.isfinite(y[int(np.argmax(bad_rows))])))]
        where = ", ".join(f"rows {a}-{b - 1}" if b - a > 1 else f"row {a}" for a, b in runs[:5])
        more = f" and {len(runs) - 5} more" if len(runs) > 5 else ""
        msg = f"{source}: column {col}: {int(bad_rows.sum())} NaN/missing sample(s) in {len(runs)} gap(s) at {where}{more}"
        if gap_policy == "error":
            raise AnalysisError(msg + " (choose a gap policy: longest or split)")
        warnings.append(msg + f" (gap policy {gap_policy})")
    segments = [y[a:b] for a, b in _runs(~bad_rows)] if bad_rows.any() else [y]
    if gap_policy == "longest" and segments:
        segments = [max(segments, key=len)]
    if gap_policy == "split":
        short = sum(1 for s in segments if len(s) < MIN_SAMPLES)
        segments = [s for s in segments if len(s) >= MIN_SAMPLES]
        if short:
            warnings.append(f"{source}: {short} gap-free run(s) shorter than {MIN_SAMPLES} samples left out")
    total = sum(len(s) for s in segments)
    if total < MIN_SAMPLES:
        raise AnalysisError(f"{source}: {total} usable samples; Allan statistics need at least {MIN_SAMPLES}")
    if quantity is not None:
        _check_magnitude(segments[0][:100_000], columns, source, quantity)
    return segments, warnings


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) of the runs of True in a boolean vector."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.view(np.int8), [0]))))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def column_median(y: np.ndarray) -> np.ndarray:
    """Column medians (C,) of finite y (n, C), as ``np.median(y, axis=0)`` (whose NaN check imports
    numpy.ma, ~0.1 s of the command's start-up)."""
    k = len(y) // 2
    part = np.partition(y, [k - 1, k] if len(y) % 2 == 0 and k > 0 else [k], axis=0)
    return part[k] if len(y) % 2 else 0.5 * (part[k - 1] + part[k])


def _check_magnitude(y: np.ndarray, columns, source: str, quantity: str) -> None:
    """A static record's mean rate beyond any sensor's bias means a wrong declared unit."""
    med = column_median(y)
    limit, unit, hint = {"gyro": (0.5, "rad/s", "deg/s declared as rad/s?"),
                         "accel": (30.0, "m/s^2", "g or mg declared as m/s^2?")}[quantity]
    worst = int(np.argmax(np.abs(med)))
    if abs(med[worst]) > limit:
        raise AnalysisError(f"{source}: column {columns[worst]}: median {med[worst]:.4g} {unit} is implausible "
                            f"for a static {quantity} record ({hint})")
    if quantity == "accel" and y.shape[1] == 3:
        norm = float(column_median(np.linalg.norm(y, axis=1)[:, None])[0])
        if not 3.0 < norm < 30.0:
            raise AnalysisError(f"{source}: columns {', '.join(columns)}: median |a| = {norm:.3g} m/s^2 "
                                "is not gravity (g or mg declared as m/s^2?)")


# -- phase and kernels --------------------------------------------------------------------

def rate_buffer(n: int, n_channels: int) -> np.ndarray:
    """An empty (C, N + 1) float64 buffer whose columns 1.. are to hold N rate samples per channel.

    A reader that fills ``buf[:, 1:]`` and hands on the view ``buf[:, 1:].T`` (N, C) lets
    :func:`phase` integrate in place (``overwrite=True``): the phase is the only full-size array.
    From :data:`POPULATE_BYTES` on, the pages are mapped at once (``MAP_POPULATE``, small pages)
    where the system has it: first touches of huge pages (numpy's default for large arrays) cost
    2-5x more CPU on a virtual machine, up to 0.4 s for a 1e7 x 3 record.
    """
    size = 8 * n_channels * (n + 1)
    if size >= POPULATE_BYTES and hasattr(mmap, "MAP_POPULATE"):
        try:
            area = mmap.mmap(-1, size, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS | mmap.MAP_POPULATE)
        except OSError:
            pass
        else:
            return np.frombuffer(area, dtype=np.float64).reshape(n_channels, n + 1)
    return np.empty((n_channels, n + 1))


def _phase_target(y: np.ndarray) -> np.ndarray | None:
    """The :func:`rate_buffer` (C, N + 1) whose columns 1.. are ``y`` (N, C), or None."""
    base = y.base
    if not isinstance(base, np.ndarray) or y.shape[0] == 0 or base.dtype != np.float64:
        return None
    n, c = y.shape
    if (not base.flags.c_contiguous or not base.flags.writeable or base.size != c * (n + 1)
            or y.strides != (8, 8 * (n + 1)) or y.ctypes.data != base.ctypes.data + 8):
        return None
    return base.reshape(c, n + 1)


def phase(y: np.ndarray, rate: float, compiled: bool | None = None, overwrite: bool = False) -> np.ndarray:
    """Phase (C, N+1) from rate samples (N, C): x_0 = 0, x_k = dt cumsum(y - mean) (allantools).

    ``compiled``: integrate with the numba kernel in one pass (default: for records above
    :data:`COMPILED_WORK` / 20 values, whose deviations load numba anyway; numpy otherwise,
    channel by channel in place, no temporaries).
    ``overwrite``: when ``y`` is the view ``buf[:, 1:].T`` of a :func:`rate_buffer`, the phase
    replaces the samples in ``buf`` (returned; ``y`` is then overwritten) instead of a new array.
    """
    y = np.asarray(y, float)
    if y.ndim == 1:
        y = y[:, None]
    target = _phase_target(y) if overwrite else None
    x = target if target is not None else np.empty((y.shape[1], y.shape[0] + 1))
    if compiled is None:
        compiled = y.size > COMPILED_WORK / 20
    if compiled:  # in place too: each sample is read before its phase point is written
        from workbench.analysis import allan_kernels as kern

        mean = kern.column_sums(y) / len(y)
        kern.integrate(y, mean, 1.0 / float(rate), np.zeros(y.shape[1]), x[:, 1:])
        x[:, 0] = 0.0
        return x
    dt = 1.0 / float(rate)
    for c in range(y.shape[1]):
        xc = x[c, 1:]
        np.subtract(y[:, c], np.mean(y[:, c]), out=xc)  # xc is y[:, c] itself when overwriting
        np.cumsum(xc, out=xc)
        xc *= dt
    x[:, 0] = 0.0
    return x


def _mdev_start(x: np.ndarray, lags: np.ndarray) -> np.ndarray:
    """First inner sum v_0 = sum_{i<m} x[i+2m] - 2x[i+m] + x[i], (K, C)."""
    return np.array([[np.sum(xc[2 * m:3 * m] - 2 * xc[m:2 * m] + xc[:m]) for xc in x] for m in lags]).reshape(
        len(lags), x.shape[0])


def squared_sums(x: np.ndarray, lags: np.ndarray, kind: str, compiled: bool | None = None) -> np.ndarray:
    """Sums of squared differences (K, C) of the whole phase ``x`` (C, L) for ``kind``.

    ``compiled``: use the numba kernels (default: MDEV always, the others when the work, lags x
    channels x points, exceeds :data:`COMPILED_WORK`).
    """
    lags = np.asarray(lags, np.int64)
    out = np.zeros((len(lags), x.shape[0]))
    if len(lags) == 0:
        return out
    n = np.maximum(_n_terms(kind, x.shape[1], lags), 0).astype(np.int64)
    if compiled is None:
        compiled = kind == "mdev" or float(n.sum()) * x.shape[0] > COMPILED_WORK
    if not compiled:
        return _numpy_sums(x, lags, ORDER[kind], n)
    from workbench.analysis import allan_kernels as kern

    if kind == "mdev":
        v0 = _mdev_start(x, lags)
        kern.mdev_sums(x, lags, np.zeros_like(lags), n, v0, np.zeros_like(v0), out)
    else:
        kern.diff_sums(x, lags, ORDER[kind], np.zeros_like(lags), n, out)
    return out


def _numpy_sums(x: np.ndarray, lags: np.ndarray, order: int, n: np.ndarray) -> np.ndarray:
    """:func:`squared_sums` of OADEV (order 2) / OHDEV (order 3) with numpy, one (C, L) buffer reused."""
    out = np.zeros((len(lags), x.shape[0]))
    buf = np.empty((x.shape[0], int(n.max()) if len(n) else 0))
    for k, (m, nk) in enumerate(zip(lags.tolist(), n.tolist())):
        if nk <= 0:
            continue
        d = buf[:, :nk]
        if order == 2:  # x[i+2m] - 2 x[i+m] + x[i]
            np.subtract(x[:, 2 * m:2 * m + nk], x[:, m:m + nk], out=d)
            d -= x[:, m:m + nk]
            d += x[:, :nk]
        else:  # x[i+3m] - 3 x[i+2m] + 3 x[i+m] - x[i]
            np.subtract(x[:, 2 * m:2 * m + nk], x[:, m:m + nk], out=d)
            d *= -3.0
            d += x[:, 3 * m:3 * m + nk]
            d -= x[:, :nk]
        out[k] = np.einsum("ij,ij->i", d, d)
    return out


def normalise(kind: str, sums: np.ndarray, n: np.ndarray, m: np.ndarray, rate: float) -> np.ndarray:
    """Deviation (K, C) from pooled sums (K, C), term counts n (K,), factors m (K,)."""
    tau = m / rate
    denom = {"oadev": 2.0, "ohdev": 6.0, "mdev": 2.0}[kind] * tau ** 2 * n
    if kind == "mdev":
        denom = denom * m.astype(float) ** 2
    return np.sqrt(sums / denom[:, None])


# -- public entry point -------------------------------------------------------------------

def deviation(y: np.ndarray, rate: float, kind: str = "oadev", taus: str | np.ndarray = "octave",
              columns: tuple[str, ...] | list[str] | None = None, gap_policy: str = "error",
              quantity: str | None = None, source: str = "data") -> DeviationCurve:
    """Deviation ``kind`` (oadev | mdev | ohdev) of rate samples ``y`` (N,) or (N, C) at ``rate`` Hz.

    ``y`` in SI (rad/s for gyros, m/s^2 for accels); the curve is in the same unit. ``taus`` as
    :func:`averaging_factors`; ``gap_policy`` and ``quantity`` as :func:`prepare_rate_data`
    (with ``"split"`` the differences of every gap-free run are pooled and the tau grid is
    that of the longest run).
    """
    if kind not in KINDS:
        raise AnalysisError(f"{source}: deviation kind {kind!r} is not one of {', '.join(KINDS)}")
    if not (np.isfinite(rate) and rate > 0):
        raise AnalysisError(f"{source}: sample rate {rate!r} Hz must be positive")
    y = np.asarray(y, float)
    cols = tuple(columns) if columns is not None else tuple(f"ch{i}" for i in range(1 if y.ndim == 1 else y.shape[1]))
    segments, _ = prepare_rate_data(y, cols, source, gap_policy, quantity)
    return segment_deviation(segments, rate, kind, taus, cols, source)[0]


def segment_deviation(segments: list[np.ndarray], rate: float, kind: str, taus: str | np.ndarray,
                      columns: tuple[str, ...], source: str = "data", overwrite: bool = False,
                      compiled: bool | None = None) -> tuple[DeviationCurve, np.ndarray]:
    """:func:`deviation` of checked gap-free segments (:func:`prepare_rate_data`), and the phase
    (C, L) of the longest one (for the noise identification), each phase computed once.
    ``overwrite``: a segment that is a :func:`rate_buffer` view is replaced by its phase (:func:`phase`);
    ``compiled`` as :func:`squared_sums` (True: numba is loaded anyway, e.g. by the IEEE 952 fit)."""
    longest = max(segments, key=len)
    m = averaging_factors(len(longest) + 1, taus, rate, kind)
    if len(m) == 0:
        raise AnalysisError(f"{source}: no averaging time fits {len(longest)} samples for {kind}")
    sums = np.zeros((len(m), len(columns)))
    n = np.zeros(len(m), np.int64)
    x_longest = None
    for seg in segments:
        n_seg = _n_terms(kind, len(seg) + 1, m)
        use = n_seg > 0
        x = phase(seg, rate, compiled, overwrite)
        sums[use] += squared_sums(x, m[use], kind, compiled)
        n[use] += n_seg[use]
        if seg is longest:
            x_longest = x
        del x
    curve = DeviationCurve(kind, m / rate, m, normalise(kind, sums, n, m, rate), n, float(rate),
                           sum(len(s) for s in segments), columns)
    return curve, x_longest
