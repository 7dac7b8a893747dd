"""One stream of a recording: read its table, convert its columns to SI, find its sampling instants.

A stream is one file of a recording (``streams.NAME`` of an import profile, or the one file of
a single-file profile), or one topic / message of a log (:mod:`workbench.importers.readers`).
:func:`read_stream` reads it, converts the profile's columns (unit,
``scale``, ``offset``: lab units to SI through :mod:`workbench.units`), reconstructs the
sampling instants (a time column, a sample counter, the row number at the rate, or a sample
clock fitted to host arrival stamps: :mod:`workbench.importers.clock`) and detects repeated
samples (every value equal to the previous sample's: a sensor read faster than it updates)
and saturated samples (a value at the stream's declared ``range``).

Public: :class:`Stream`, :func:`read_stream`, :func:`damage_entry`, :data:`TRIAD_OF`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from workbench.errors import ImportProfileError
from workbench.importers.clock import ClockFit, fit_arrival_clock
from workbench.importers.damage import Damage
from workbench.importers.readers import read_log
from workbench.session import ACCEL, GYRO, MAG
from workbench.units import factor

TRIAD_OF = {**{c: "gyro" for c in GYRO}, **{c: "accel" for c in ACCEL}, **{c: "mag" for c in MAG}}
SI_UNIT = {**{c: "rad/s" for c in GYRO}, **{c: "m/s^2" for c in ACCEL}, **{c: "uT" for c in MAG},
           "temp": "degC", "table_angle": "rad", "table_rate": "rad/s"}
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
RATE_TOLERANCE = 0.10  # a declared rate_hz this far from the stamps' is refused (hobby clocks: a few % off)


@dataclass(frozen=True)
class Stream:
    """One stream, SI: ``t`` (N,) sampling instants on the recording's clock, s; ``values`` the
    converted columns (targets as in the session, e.g. ``gx``, ``temp``); ``repeated`` (N,) the
    sample repeats the previous one exactly; ``saturated`` (N,) a value is at the declared range;
    ``clock`` the arrival-stamp fit (None for other time sources); ``index`` (N,) sample counter
    (row number unless a counter column is declared); ``trailing_zero_rows`` all-zero rows dropped
    from the end (``reader: {trailing_zero_rows: drop}``: a recorder's unfilled buffer); ``damage`` what of a
    truncated or corrupt log could not be read (:func:`damage_entry`), None when it was whole."""

    name: str
    source: str
    t: np.ndarray
    values: pd.DataFrame
    repeated: np.ndarray
    saturated: np.ndarray
    clock: ClockFit | None
    index: np.ndarray
    checks_repeats: bool
    trailing_zero_rows: int = 0
    damage: dict | None = None

    @property
    def triads(self) -> tuple[str, ...]:
        """Triads ('gyro', 'accel', 'mag') with at least one column in this stream."""
        return tuple(dict.fromkeys(TRIAD_OF[c] for c in self.values.columns if c in TRIAD_OF))

    @property
    def rate_hz(self) -> float:
        """Mean sample rate of the instants, Hz (the fitted clock's rate for arrival stamps)."""
        if self.clock is not None:
            return self.clock.rate_hz
        return float(1.0 / np.median(np.diff(self.t))) if len(self.t) > 1 else float("nan")


def _columns_text(raw: pd.DataFrame) -> str:
    """The file's first column names for an error; a file read as one column hints at the delimiter."""
    hint = "; one column only: is reader.delimiter the file's?" if len(raw.columns) == 1 else ""
    return f"(columns: {', '.join(map(str, raw.columns[:12]))}{hint})"


def _column(raw: pd.DataFrame, col, where: str) -> np.ndarray:
    if col not in raw.columns:
        raise ImportProfileError(f"{where}: column {col!r} not in the file {_columns_text(raw)}")
    values = pd.to_numeric(raw[col], errors="coerce").to_numpy(float)
    bad = ~np.isfinite(values)
    if bad.any():
        row = int(np.argmax(bad))
        cell = raw[col].iloc[row]
        raise ImportProfileError(f"{where}: column {col!r}: not a finite number at row {row} "
                                 f"({cell.item() if hasattr(cell, 'item') else cell!r})")
    return values


def convert(raw: pd.DataFrame, columns: Mapping, where: str) -> pd.DataFrame:
    """The profile's ``columns`` of ``raw`` in SI (value * scale + offset, then unit -> SI)."""
    out = {}
    for target, spec in columns.items():
        if spec["column"] not in raw.columns:
            raise ImportProfileError(f"{where}: profile column {spec['column']!r} (for {target}) not in the file "
                                     f"{_columns_text(raw)}")
        values = _column(raw, spec["column"], f"{where}: columns.{target}")
        values = values * float(spec.get("scale", 1.0)) + float(spec.get("offset", 0.0))
        unit = spec.get("unit", SI_UNIT[target])
        out[target] = values if unit == "degC" else values * factor(unit) / factor(SI_UNIT[target])
    return pd.DataFrame(out)


def _clock(t: np.ndarray, rate: float | None, where: str, clocks: dict) -> ClockFit:
    """The clock fit of stamps ``t``, reused from ``clocks`` when another stream had the same stamps."""
    import hashlib

    key = (hashlib.sha1(t.tobytes()).hexdigest(), rate)
    if key not in clocks:
        clocks[key] = fit_arrival_clock(t, rate, where)
    return clocks[key]


def _instants(raw: pd.DataFrame, spec: Mapping, where: str,
              clocks: dict) -> tuple[np.ndarray, ClockFit | None, np.ndarray]:
    """Sampling instants (s, first = raw stamp), the clock fit for arrival stamps, the sample counter."""
    tspec = spec.get("time") or {}
    rate = spec.get("rate_hz")
    n = len(raw)
    if "column" in tspec:
        t = _column(raw, tspec["column"], f"{where}: time.column") * TIME_UNITS[tspec.get("unit", "s")]
        if tspec.get("stamps", "sample") == "arrival":
            clock = _clock(t, rate, f"{where}: time.column {tspec['column']!r}", clocks)
            if rate and abs(clock.rate_hz - rate) > RATE_TOLERANCE * rate:
                raise ImportProfileError(f"{where}: rate_hz {rate:g} Hz: the arrival stamps give {clock.rate_hz:.4g} Hz "
                                         f"(more than {RATE_TOLERANCE:.0%} off; a wrong file or rate?)")
            return clock.instants, clock, np.arange(n)  # sections count the file's rows
        return t, None, np.arange(n)
    if "counter" in tspec:
        counter = _column(raw, tspec["counter"], f"{where}: time.counter")
        return counter / float(rate), None, counter
    return np.arange(n) / float(rate), None, np.arange(n)


def read_stream(name: str, spec: Mapping, path: Path, reader: Mapping, where: str,
                clocks: dict | None = None) -> Stream:
    """Read stream ``name`` from ``path`` as ``spec`` (a checked profile entry) says; ``where`` names it in errors.

    ``clocks`` (shared by the streams of one recording) keeps the arrival-clock fits by stamps, so
    files of one read (the same stamps) are fitted once."""
    reader = {**reader, **(spec.get("reader") or {})}
    raw, damage = read_log(path, reader, where)
    trailing = 0
    if reader.get("trailing_zero_rows") == "drop":  # a preallocated buffer the recorder did not fill
        used = [c for c in raw.columns if c in _used_columns(spec)]
        zero = (raw[used].apply(pd.to_numeric, errors="coerce") == 0).all(axis=1).to_numpy()
        trailing = len(zero) - (int(np.flatnonzero(~zero)[-1]) + 1 if (~zero).any() else 0)
        raw = raw.iloc[:len(raw) - trailing]
    if len(raw) == 0:
        raise ImportProfileError(f"{where}: no rows" if where == str(path) else f"{where}: {path.name}: no rows")
    values = convert(raw, spec["columns"], where)
    t, clock, index = _instants(raw, spec, where, {} if clocks is None else clocks)
    lost = damage_entry(damage, path.name, float(t[-1])) if damage is not None and damage.any else None
    if lost is not None and len(t) < 2:
        raise ImportProfileError(f"{where}: {lost['text']}: {len(t)} sample left; nothing to import")
    if np.any(np.diff(t) <= 0):
        row = int(np.argmax(np.diff(t) <= 0)) + 1
        raise ImportProfileError(f"{where}: time: duplicate or non-increasing time at row {row} (t={t[row]})")
    vector = [c for c in values.columns if c in TRIAD_OF]
    checks = bool(spec.get("repeats", "flag" if vector else "ignore") == "flag") and bool(vector)
    v = values[vector].to_numpy() if vector else np.zeros((len(values), 0))
    repeated = np.zeros(len(values), bool)
    if checks and len(v) > 1:
        repeated[1:] = np.all(v[1:] == v[:-1], axis=1)
    saturated = np.zeros(len(values), bool)
    rng = spec.get("range")
    if rng is not None:
        dim = SI_UNIT[vector[0]]
        limit = float(rng["value"]) * factor(rng.get("unit", dim)) / factor(dim)
        # the rail itself, one LSB either way: |value| >= the declared full scale
        saturated = np.any(np.abs(v) >= limit * (1 - 1e-9), axis=1)
    return Stream(name, str(path), t, values, repeated, saturated, clock, index, checks, trailing, lost)


def damage_entry(damage: Damage, name: str, last_t: float) -> dict:
    """JSON-ready record of a damaged log for the import summary; ``last_t`` the stream's last instant, s."""
    return {"file_bytes": damage.file_bytes, "cut_bytes": damage.cut_bytes, "cut_message_bytes": damage.cut_of,
            "skipped_bytes": damage.skipped_bytes, "corrupt": damage.corrupt, "last_time_s": last_t,
            "text": damage.text(name)}


def _used_columns(spec: Mapping) -> set:
    tspec = spec.get("time") or {}
    return {c["column"] for c in spec["columns"].values()} | {tspec[k] for k in ("column", "counter") if k in tspec}
