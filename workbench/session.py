"""Sessions: one run of a sequence on a unit, as ``session.json`` + ``samples.parquet``.

The format (``workbench-session/1``) is documented in ``docs/formats.md``. A session
recorded by another tool in this format (``samples.csv`` accepted in place of Parquet) is
analysed exactly like one recorded by the runner. Loading validates the manifest and the
samples and raises :class:`SessionError` naming the file, column or step at fault.

Frames: ``mount`` takes body-frame vectors into the table-top frame (x along the table's
zero, z down); the body-to-NED attitude at table angle ``a`` is
``Rz(table_zero_azimuth + a) @ mount``.
"""

from __future__ import annotations

import json
import uuid
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from workbench.earth import normal_gravity, rz
from workbench.errors import SessionError
from workbench.files import atomic_write_text, file_sha256
from workbench.values import ACCEL, GYRO, MAG, Unit

FORMAT = "workbench-session/1"
STEP_LOG = "steps.jsonl"  # an unfinished recording's completed steps, one JSON object a line (runner.py)
STEP_KINDS = ("static", "rate", "index", "carousel", "soak", "ramp", "drive", "free")  # free: by hand, no table
REQUIRED_COLUMNS = ["t", "step", *GYRO, *ACCEL]
OPTIONAL_COLUMNS = [*MAG, "temp", "table_angle", "table_rate", "odo_distance", "flags"]
# bits of the optional ``flags`` column (imported recordings): a set bit leaves the sample out of that triad's fits
FLAG_SATURATED = {"gyro": 1, "accel": 2, "mag": 4}  # a value at the stream's declared range
FLAG_REPEATED = {"gyro": 32, "accel": 16, "mag": 8}  # a stale read: the sensor had not updated


@dataclass(frozen=True)
class Site:
    """Where the rig stands. Angles stored in degrees as in the file; radians via properties."""

    latitude_deg: float
    longitude_deg: float = 0.0
    height_m: float = 0.0
    table_zero_azimuth_deg: float | None = None
    field_norm_ut: float | None = None  # reference magnetic-field magnitude at the rig, µT (None = unknown)

    @property
    def latitude(self) -> float:
        """Geodetic latitude, rad."""
        return float(np.radians(self.latitude_deg))

    @property
    def table_zero_azimuth(self) -> float | None:
        """Azimuth of the table's zero direction clockwise from true north, rad (None = unknown)."""
        return None if self.table_zero_azimuth_deg is None else float(np.radians(self.table_zero_azimuth_deg))

    @property
    def gravity(self) -> float:
        """Normal gravity magnitude at the site, m/s^2."""
        return float(normal_gravity(self.latitude, self.height_m))

    def to_dict(self) -> dict:
        out = {"latitude_deg": self.latitude_deg, "longitude_deg": self.longitude_deg,
               "height_m": self.height_m, "table_zero_azimuth_deg": self.table_zero_azimuth_deg}
        if self.field_norm_ut is not None:
            out["field_norm_ut"] = self.field_norm_ut
        return out


@dataclass(frozen=True)
class StepRecord:
    """What the rig did during one step (a row of ``session.json`` ``steps``).

    ``mount`` (3, 3) body->table-top; ``table_angle`` rad at ``t_start``; ``table_rate`` rad/s
    commanded (0 when static); ``temperature_c`` the chamber setpoint (None if no chamber);
    ``extra`` holds any further keys (e.g. ``label``, ``revolutions``, ``index_angle``).
    """

    index: int
    kind: str
    t_start: float
    t_end: float
    mount: np.ndarray = field(default_factory=lambda: np.eye(3))
    table_angle: float = 0.0
    table_rate: float = 0.0
    temperature_c: float | None = None
    label: str = ""
    extra: Mapping[str, object] = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Step duration, s."""
        return self.t_end - self.t_start

    def to_dict(self) -> dict:
        out = {"index": self.index, "kind": self.kind, "t_start": self.t_start, "t_end": self.t_end,
               "mount": np.asarray(self.mount).tolist(), "table_angle": self.table_angle,
               "table_rate": self.table_rate, "temperature_c": self.temperature_c, "label": self.label}
        out.update(self.extra)
        return out

    @classmethod
    def from_dict(cls, d: Mapping, source: str = "session.json") -> StepRecord:
        known = {"index", "kind", "t_start", "t_end", "mount", "table_angle", "table_rate", "temperature_c", "label"}
        try:
            idx = int(d["index"])
        except (KeyError, TypeError, ValueError):
            raise SessionError(f"{source}: a step has no integer 'index'") from None
        where = f"{source}: step {idx}"
        for key in ("kind", "t_start", "t_end"):
            if key not in d:
                raise SessionError(f"{where}: missing field {key!r}")
        if d["kind"] not in STEP_KINDS:
            raise SessionError(f"{where}: unknown kind {d['kind']!r} (expected one of {', '.join(STEP_KINDS)})")
        mount = np.array(d.get("mount", np.eye(3)), float)
        if mount.shape != (3, 3) or not np.all(np.isfinite(mount)):
            raise SessionError(f"{where}: 'mount' must be a finite 3x3 matrix")
        if not np.allclose(mount @ mount.T, np.eye(3), atol=1e-6) or np.linalg.det(mount) < 0:
            raise SessionError(f"{where}: 'mount' is not a rotation matrix")
        t0, t1 = float(d["t_start"]), float(d["t_end"])
        if not t1 > t0:
            raise SessionError(f"{where}: t_end {t1} is not after t_start {t0}")
        temp = d.get("temperature_c")
        return cls(idx, d["kind"], t0, t1, mount, float(d.get("table_angle") or 0.0),
                   float(d.get("table_rate") or 0.0), None if temp is None else float(temp),
                   str(d.get("label", "")), {k: v for k, v in d.items() if k not in known})


@dataclass
class Session:
    """A loaded session: manifest fields, step records and the samples table."""

    id: str
    unit: Unit
    site: Site
    sample_rate_hz: float
    procedure: str
    steps: list[StepRecord]
    samples: pd.DataFrame | None  # None for a lazily loaded session: use stream()
    path: Path | None = None
    options: Mapping[str, object] = field(default_factory=dict)
    rig: str | None = None
    created: str | None = None

    # -- access ---------------------------------------------------------------------
    def step(self, index: int) -> StepRecord:
        """The step record with ``index``."""
        for s in self.steps:
            if s.index == index:
                return s
        raise SessionError(f"{self.name}: no step {index}")

    def step_samples(self, index: int) -> pd.DataFrame:
        """Samples labelled with step ``index`` (a row slice: a step's samples are contiguous)."""
        rows = self._step_rows().get(index)
        if rows is None:
            return self.samples.iloc[0:0]
        if isinstance(rows, slice):
            return self.samples.iloc[rows]
        return self.samples[rows]

    def _step_rows(self) -> dict:
        """Row slice (or boolean mask, for a step whose rows are not contiguous) of every step label."""
        cache = self.__dict__.get("_rows")
        if cache is None or cache[0] is not self.samples:
            labels = self.samples["step"].to_numpy()
            rows: dict = {}
            if len(labels):
                change = np.flatnonzero(np.diff(labels)) + 1
                starts, stops = np.r_[0, change], np.r_[change, len(labels)]
                for a, b in zip(starts, stops):
                    lab = int(labels[a])
                    rows[lab] = slice(int(a), int(b)) if lab not in rows else labels == lab
            cache = (self.samples, rows)
            self.__dict__["_rows"] = cache
        return cache[1]

    def steps_of_kind(self, *kinds: str) -> list[StepRecord]:
        """Step records whose kind is one of ``kinds``."""
        return [s for s in self.steps if s.kind in kinds]

    @property
    def has_mag(self) -> bool:
        """Whether the samples have magnetometer columns (read from the file's schema when lazy)."""
        if self.samples is not None:
            return all(c in self.samples.columns for c in MAG)
        import pyarrow.parquet as pq

        return all(c in pq.read_schema(self.path / "samples.parquet").names for c in MAG)

    @property
    def name(self) -> str:
        return str(self.path) if self.path is not None else f"session {self.id}"

    def gyro(self, index: int | None = None) -> np.ndarray:
        """Gyro samples (N, 3) rad/s, body frame; all samples or step ``index``."""
        return self._cols(GYRO, index)

    def accel(self, index: int | None = None) -> np.ndarray:
        """Accelerometer samples (N, 3) m/s^2, body frame."""
        return self._cols(ACCEL, index)

    def mag(self, index: int | None = None) -> np.ndarray:
        """Magnetometer samples (N, 3) µT, body frame."""
        if not self.has_mag:
            raise SessionError(f"{self.name}: samples have no magnetometer columns mx, my, mz")
        return self._cols(MAG, index)

    def good(self, triad: str, index: int | None = None) -> np.ndarray:
        """(N,) bool: the samples (all, or of step ``index``) whose ``flags`` leave ``triad`` usable in fits
        (no saturated or repeated bit of that triad; all True without a ``flags`` column)."""
        df = self.samples if index is None else self.step_samples(index)
        if "flags" not in df.columns:
            return np.ones(len(df), bool)
        bits = FLAG_SATURATED[triad] | FLAG_REPEATED[triad]
        return (df["flags"].to_numpy(np.int64) & bits) == 0

    def _cols(self, cols: list[str], index: int | None) -> np.ndarray:
        if self.samples is None:
            raise SessionError(f"{self.name}: loaded lazily (a long record); read it with Session.stream()")
        df = self.samples if index is None else self.step_samples(index)
        return df[cols].to_numpy(float)

    def stream(self, columns: list[str], step: int | None = None, batch_rows: int = 1 << 20) -> Iterator[np.ndarray]:
        """The samples of ``columns`` (all, or step ``step``) as consecutive (n, C) float blocks.

        Memory is bounded by ``batch_rows`` for a lazily loaded session (Parquet row batches);
        an in-memory session is sliced.
        """
        if self.samples is not None:
            df = self.samples if step is None else self.step_samples(step)
            values = df[columns].to_numpy(float)
            for i in range(0, len(values), batch_rows):
                yield values[i:i + batch_rows]
            return
        import pyarrow.parquet as pq

        pf = pq.ParquetFile(self.path / "samples.parquet", pre_buffer=False)  # pre-buffering grows with the file
        for batch in pf.iter_batches(batch_size=batch_rows, columns=[*columns, "step"]):
            block = np.column_stack([batch.column(c).to_numpy(zero_copy_only=False) for c in columns]).astype(float)
            if step is not None:
                block = block[batch.column("step").to_numpy(zero_copy_only=False) == step]
            if len(block):
                yield block

    def attitude(self, step: StepRecord, table_angle: float | np.ndarray | None = None) -> Rotation:
        """Body-to-NED rotation at ``table_angle`` (rad; default the step's start angle).

        Uses the site's table zero azimuth; raises if it is unknown (gravity-only analyses
        should use :meth:`table_attitude`, which does not need it).
        """
        az = self.site.table_zero_azimuth
        if az is None:
            raise SessionError(f"{self.name}: site.table_zero_azimuth_deg is unknown (null)")
        return rz(az) * self.table_attitude(step, table_angle)

    def table_attitude(self, step: StepRecord, table_angle: float | np.ndarray | None = None) -> Rotation:
        """Body-to-table-zero-frame rotation (a level frame whose x is the table's zero)."""
        angle = step.table_angle if table_angle is None else table_angle
        return rz(angle) * Rotation.from_matrix(step.mount)

    def samples_sha256(self) -> str | None:
        """SHA-256 of the samples file (None for a session that is not on disk); read once."""
        f = samples_file(self.path) if self.path is not None else None
        if f is None:
            return None
        cached = self.__dict__.get("_sha256")
        if cached is None or cached[0] != f:
            cached = (f, file_sha256(f))
            self.__dict__["_sha256"] = cached
        return cached[1]

    def manifest(self) -> dict:
        """The ``session.json`` dict."""
        return {
            "format": FORMAT, "id": self.id,
            "unit": {"serial": self.unit.serial, "model": self.unit.model},
            "site": self.site.to_dict(), "sample_rate_hz": self.sample_rate_hz,
            "procedure": self.procedure, "options": dict(self.options), "rig": self.rig,
            "created": self.created, "steps": [s.to_dict() for s in self.steps],
        }


def samples_file(directory: Path) -> Path | None:
    """The samples file of a session folder (Parquet preferred, then CSV), or None."""
    for name in ("samples.parquet", "samples.csv"):
        if (directory / name).exists():
            return directory / name
    return None


def _load_manifest(directory: Path) -> dict:
    mpath = directory / "session.json"
    if not directory.is_dir():
        raise SessionError(f"{directory}: not a session folder")
    if not mpath.exists():
        raise SessionError(f"{directory}: no session.json")
    try:
        data = json.loads(mpath.read_text())
    except json.JSONDecodeError as exc:
        raise SessionError(f"{mpath}: not valid JSON (line {exc.lineno}: {exc.msg})") from None
    fmt = data.get("format")
    if fmt != FORMAT:
        raise SessionError(f"{mpath}: format {fmt!r} is not {FORMAT!r}")
    return data


def step_log(directory: Path) -> list[dict]:
    """The entries (``{"step": {...}, "rig_state": {...}}``) of an unfinished recording's step log.

    In step order, the last entry of a step index winning (a step recorded again on resume);
    a last line cut short by a kill is ignored. Empty when there is no log.
    """
    try:
        lines = (Path(directory) / STEP_LOG).read_text().splitlines()
    except FileNotFoundError:
        return []
    entries: dict[int, dict] = {}
    for n, line in enumerate(lines):
        try:
            entry = json.loads(line)
        except json.JSONDecodeError:
            if n == len(lines) - 1:
                break  # the line being written when the recording was killed
            raise SessionError(f"{directory / STEP_LOG}: line {n + 1} is not valid JSON") from None
        entries[int(entry["step"]["index"])] = entry
    return [entries[i] for i in sorted(entries)]


def recorded_steps(directory: Path, manifest: Mapping) -> list[dict]:
    """The completed steps of a session folder: the manifest's, and those of the step log of a
    recording that has not finished (the manifest is rewritten only when it finishes)."""
    steps = list(manifest.get("steps", []))
    if manifest.get("complete"):
        return steps
    logged = step_log(directory)
    known = {s.get("index") for s in steps}
    return steps + [e["step"] for e in logged if e["step"]["index"] not in known]


def parse_manifest(data: Mapping, source: str) -> tuple[dict, list[StepRecord]]:
    """Validate a manifest dict; returns (fields, step records)."""
    for key in ("unit", "site", "sample_rate_hz", "steps"):
        if key not in data:
            raise SessionError(f"{source}: missing field {key!r}")
    site = data["site"]
    if not isinstance(site, Mapping) or site.get("latitude_deg") is None:
        raise SessionError(f"{source}: site.latitude_deg is missing")
    lat = float(site["latitude_deg"])
    if not -90 <= lat <= 90:
        raise SessionError(f"{source}: site.latitude_deg {lat} is outside -90..90")
    rate = data["sample_rate_hz"]
    if not isinstance(rate, (int, float)) or not rate > 0:
        raise SessionError(f"{source}: sample_rate_hz must be a positive number")
    steps = [StepRecord.from_dict(s, source) for s in data["steps"]]
    idx = [s.index for s in steps]
    if len(set(idx)) != len(idx):
        raise SessionError(f"{source}: duplicate step index")
    ordered = sorted(steps, key=lambda s: s.t_start)
    for a, b in zip(ordered, ordered[1:]):
        if b.t_start < a.t_end - 1e-9:
            raise SessionError(f"{source}: step {b.index} overlaps step {a.index}")
    return dict(data), steps


GAP_FACTOR = 2.5  # an interval longer than 2.5 nominal sample intervals is a gap
RATE_TOLERANCE = 0.01  # sample_rate_hz may differ from the time column's rate by 1 %


def _check_time_base(t: np.ndarray, labels: np.ndarray, sample_rate_hz: float, source: str,
                     gaps_in_steps: bool) -> None:
    """Check the time column (s) against ``sample_rate_hz`` and allow gaps only between steps.

    A gap (an interval over :data:`GAP_FACTOR` nominal intervals) is normal where the recorder
    paused between steps: the samples either side carry different step labels, or one of them
    is unlabelled (``step = -1``). A gap inside a step is an error naming the step unless
    ``gaps_in_steps`` (a gap-aware analysis). The rate is the median interval of consecutive
    samples inside steps (or of all samples when nothing is labelled); more than
    :data:`RATE_TOLERANCE` off ``sample_rate_hz`` is an error naming both.
    """
    dt = np.diff(t)
    if not len(dt):
        return
    nominal = 1.0 / sample_rate_hz
    same = (labels[1:] == labels[:-1]) & (labels[1:] >= 0)
    inside = dt[same] if same.any() else dt
    measured = 1.0 / float(np.median(inside))
    if abs(measured - sample_rate_hz) > RATE_TOLERANCE * sample_rate_hz:
        raise SessionError(f"{source}: sample_rate_hz {sample_rate_hz:g} Hz disagrees with column t, whose median "
                           f"interval gives {measured:.4g} Hz (more than {RATE_TOLERANCE:.0%} off)")
    gap = (dt > GAP_FACTOR * nominal) & same
    if gap.any() and not gaps_in_steps:
        row = int(np.argmax(gap)) + 1
        raise SessionError(f"{source}: step {int(labels[row])}: column t: gap of {dt[row - 1]:.4g} s before row "
                           f"{row} (t={t[row]}) inside the step, sample interval {nominal:.4g} s "
                           "(gaps are allowed only between steps)")


def validate_samples(df: pd.DataFrame, steps: Sequence[StepRecord], sample_rate_hz: float, source: str,
                     require_complete: bool = True, check_labels: bool = True,
                     gaps_in_steps: bool = False) -> pd.DataFrame:
    """Check columns, finiteness, time order, time base and step labels; raise SessionError naming the problem.

    Gaps in time are allowed between steps (see :func:`_check_time_base`); ``gaps_in_steps``
    also allows them inside steps (for gap-aware analyses).
    """
    missing = [c for c in REQUIRED_COLUMNS if c not in df.columns]
    if missing:
        raise SessionError(f"{source}: missing column(s) {', '.join(missing)}")
    if len(df) == 0:
        raise SessionError(f"{source}: no samples")
    for col in [c for c in REQUIRED_COLUMNS + OPTIONAL_COLUMNS if c in df.columns]:
        try:
            values = df[col].to_numpy(float)
        except (TypeError, ValueError):
            raise SessionError(f"{source}: column {col}: not numeric ({df[col].dtype} values)") from None
        bad = ~np.isfinite(values)
        if bad.any():
            row = int(np.argmax(bad))
            raise SessionError(f"{source}: column {col}: NaN or infinite value at row {row} (t={df['t'].iloc[row]})")
    t = df["t"].to_numpy(float)
    dt = np.diff(t)
    if np.any(dt <= 0):
        row = int(np.argmax(dt <= 0)) + 1
        raise SessionError(f"{source}: column t: duplicate or non-increasing time at row {row} (t={t[row]})")
    labels = df["step"].to_numpy()
    _check_time_base(t, labels, sample_rate_hz, source, gaps_in_steps)
    nominal = 1.0 / sample_rate_hz
    _check_units(df, source)
    if not check_labels:
        return df
    known = {s.index for s in steps}
    unknown = set(np.unique(labels)) - known - {-1}
    if unknown:
        raise SessionError(f"{source}: column step: label(s) {sorted(unknown)[:5]} match no step in session.json")
    for s in steps:
        sel = labels == s.index
        if s.t_start < t[0] - 1.5 * nominal or s.t_end > t[-1] + 1.5 * nominal:
            raise SessionError(f"{source}: step {s.index} ({s.t_start:.3f}..{s.t_end:.3f} s) points outside "
                               f"the samples ({t[0]:.3f}..{t[-1]:.3f} s)")
        if require_complete and not sel.any():
            raise SessionError(f"{source}: step {s.index} ({s.kind}) has no samples")
        if sel.any():
            ts = t[sel]
            _check_step_span(source, s, float(ts[0]), float(ts[-1]), nominal, gaps_in_steps)
    return df


def _check_step_span(source: str, s: StepRecord, first: float, last: float, nominal: float,
                     gaps_in_steps: bool) -> None:
    """A step's samples (first..last, s) lie within its t_start..t_end and, unless gaps are allowed, fill it."""
    if first < s.t_start - 1.5 * nominal or last > s.t_end + 1.5 * nominal:
        raise SessionError(f"{source}: step {s.index}: samples at t={first:.3f}..{last:.3f} "
                           f"fall outside the step's t_start..t_end {s.t_start:.3f}..{s.t_end:.3f}")
    if gaps_in_steps:
        return
    for lo, hi in ((s.t_start, first), (last, s.t_end)):
        if hi - lo > GAP_FACTOR * nominal:
            raise SessionError(f"{source}: step {s.index}: column t: gap of {hi - lo:.4g} s at t={lo:.3f}..{hi:.3f} "
                               f"inside the step's t_start..t_end {s.t_start:.3f}..{s.t_end:.3f} (no samples there)")


def validate_parquet_stream(path: Path, steps: Sequence[StepRecord], sample_rate_hz: float,
                            require_complete: bool = True, batch_rows: int = 1 << 20,
                            gaps_in_steps: bool = False) -> None:
    """:func:`validate_samples` batch by batch over a Parquet file, in bounded memory.

    Each batch (with the last sample of the previous one, for time order and gaps) goes
    through the same checks; step coverage is accumulated across batches.
    """
    import pyarrow.parquet as pq

    pf = pq.ParquetFile(path, pre_buffer=False)  # pre-buffering caches every row group: memory grows with the file
    names = set(pf.schema_arrow.names)
    missing = [c for c in REQUIRED_COLUMNS if c not in names]
    if missing:
        raise SessionError(f"{path}: missing column(s) {', '.join(missing)}")
    cols = [c for c in REQUIRED_COLUMNS + OPTIONAL_COLUMNS if c in names]
    seen: dict[int, list[float]] = {}
    prev: pd.DataFrame | None = None
    offset = 0
    for batch in pf.iter_batches(batch_size=batch_rows, columns=cols):
        df = batch.to_pandas()
        chunk = df if prev is None else pd.concat([prev, df], ignore_index=True)
        try:
            validate_samples(chunk, [], sample_rate_hz, str(path), require_complete=False, check_labels=False,
                             gaps_in_steps=gaps_in_steps)
        except SessionError as exc:
            raise SessionError(f"{exc} (in the batch starting at row {offset})") from None
        lab, t = df["step"].to_numpy(), df["t"].to_numpy(float)
        for idx in np.unique(lab[lab >= 0]):
            ts = t[lab == idx]
            lo_hi = seen.setdefault(int(idx), [ts[0], ts[-1]])
            lo_hi[0], lo_hi[1] = min(lo_hi[0], ts[0]), max(lo_hi[1], ts[-1])
        prev, offset = df.iloc[-1:], offset + len(df)
    known = {s.index for s in steps}
    unknown = set(seen) - known
    if unknown:
        raise SessionError(f"{path}: column step: label(s) {sorted(unknown)[:5]} match no step in session.json")
    nominal = 1.0 / sample_rate_hz
    for s in steps:
        if s.index not in seen:
            if require_complete:
                raise SessionError(f"{path}: step {s.index} ({s.kind}) has no samples")
            continue
        lo, hi = seen[s.index]
        _check_step_span(str(path), s, lo, hi, nominal, gaps_in_steps)


def _check_units(df: pd.DataFrame, source: str) -> None:
    """Flag physically implausible magnitudes (wrong declared units)."""
    norm = np.median(np.linalg.norm(df[ACCEL].to_numpy(float), axis=1))
    if norm < 3.0 or norm > 30.0:
        raise SessionError(f"{source}: columns ax, ay, az: median |a| = {norm:.3g}, not m/s^2 "
                           "(given in g or mg? convert with an import profile)")
    gmax = np.abs(df[GYRO].to_numpy(float)).max()
    if gmax > 60.0:
        raise SessionError(f"{source}: columns gx, gy, gz: |rate| up to {gmax:.3g}, not rad/s (deg/s?)")
    if all(c in df.columns for c in MAG):
        mn = np.median(np.linalg.norm(df[MAG].to_numpy(float), axis=1))
        if mn < 1.0 or mn > 1000.0:
            raise SessionError(f"{source}: columns mx, my, mz: median |m| = {mn:.3g}, not µT (gauss or nT?)")


def read_samples(path: Path) -> pd.DataFrame:
    """Read a samples file (Parquet or CSV) into a DataFrame."""
    try:
        if path.suffix == ".parquet":
            return pd.read_parquet(path)
        return pd.read_csv(path)
    except Exception as exc:  # pyarrow / pandas raise many types for unreadable files
        raise SessionError(f"{path}: cannot read samples ({type(exc).__name__}: {str(exc)[:120]})") from None


def load_session(directory: str | Path, require_complete: bool = True, lazy: bool = False,
                 gaps_in_steps: bool = False) -> Session:
    """Load and validate a session folder (``session.json`` + ``samples.parquet|csv``).

    Time gaps between steps are normal; ``gaps_in_steps`` also accepts them inside steps
    (for a gap-aware analysis).

    ``lazy``: validate a Parquet samples file batch by batch and keep it on disk
    (``Session.samples`` is None; read it with :meth:`Session.stream`), for records larger
    than memory.
    """
    directory = Path(directory)
    data = _load_manifest(directory)
    if isinstance(data.get("steps"), list):
        data["steps"] = recorded_steps(directory, data)
    mpath = directory / "session.json"
    fields, steps = parse_manifest(data, str(mpath))
    spath = samples_file(directory)
    df: pd.DataFrame | None
    if lazy and spath is not None and spath.suffix == ".parquet":
        validate_parquet_stream(spath, steps, float(fields["sample_rate_hz"]), require_complete,
                                gaps_in_steps=gaps_in_steps)
        df = None
    elif spath is not None:
        df = read_samples(spath)
    elif (directory / "parts").is_dir():  # an interrupted recording: its completed steps
        spath = directory / "parts"
        files = sorted(spath.glob("step_*.parquet"))
        done = {s.index for s in steps}
        df = pd.concat([read_samples(f) for f in files if int(f.stem.split("_")[1]) in done] or [pd.DataFrame()],
                       ignore_index=True)
    else:
        raise SessionError(f"{directory}: no samples.parquet or samples.csv")
    if df is not None:
        validate_samples(df, steps, float(fields["sample_rate_hz"]), str(spath), require_complete,
                         gaps_in_steps=gaps_in_steps)
    u, s = fields["unit"], fields["site"]
    return Session(
        id=str(fields.get("id") or uuid.uuid5(uuid.NAMESPACE_URL, str(directory.resolve()))),
        unit=Unit(str(u.get("serial", "")), str(u.get("model", ""))),
        site=Site(float(s["latitude_deg"]), float(s.get("longitude_deg") or 0.0), float(s.get("height_m") or 0.0),
                  None if s.get("table_zero_azimuth_deg") is None else float(s["table_zero_azimuth_deg"]),
                  None if s.get("field_norm_ut") is None else float(s["field_norm_ut"])),
        sample_rate_hz=float(fields["sample_rate_hz"]),
        procedure=str(fields.get("procedure", "")),
        steps=steps,
        samples=None if df is None else df.reset_index(drop=True),
        path=directory,
        options=fields.get("options") or {},
        rig=fields.get("rig"),
        created=fields.get("created"),
    )


def write_manifest(directory: Path, manifest: Mapping) -> None:
    """Write ``session.json`` atomically."""
    atomic_write_text(directory / "session.json", json.dumps(manifest, indent=1) + "\n")


def write_session(session: Session, directory: str | Path) -> Path:
    """Write a whole in-memory session to ``directory`` (Parquet samples + manifest)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    tmp = directory / ".samples.parquet.tmp"
    session.samples.to_parquet(tmp, index=False)
    tmp.replace(directory / "samples.parquet")
    write_manifest(directory, session.manifest())
    session.path = directory
    return directory
