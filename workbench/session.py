"""Sessions: one run of a sequence on a unit, as ``session.json`` + ``samples.parquet``.

The format (``workbench-session/1``) is documented in ``docs/formats.md``. A session
recorded by another tool in this format (``samples.csv`` accepted in place of Parquet) is
analysed exactly like one recorded by the runner. Loading validates the manifest and the
samples and raises :class:`SessionError` naming the file, column or step at fault.

This module holds :class:`Session` and :func:`load_session`; the value types are in
:mod:`workbench.session_types`, the checks of the samples in :mod:`workbench.session_validate`,
the folder's files in :mod:`workbench.session_files`, all re-exported here.

Frames: ``mount`` takes body-frame vectors into the table-top frame (x along the table's
zero, z down); the body-to-NED attitude at table angle ``a`` is
``Rz(table_zero_azimuth + a) @ mount``.
"""

from __future__ import annotations

import uuid
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from workbench.earth import rz
from workbench.errors import SessionError
from workbench.files import file_sha256
from workbench.session_files import (parse_manifest, read_manifest, read_samples, recorded_steps, samples_file,
                                     step_log, write_manifest, write_session)
from workbench.session_types import (FLAG_REPEATED, FLAG_SATURATED, FORMAT, OPTIONAL_COLUMNS, REQUIRED_COLUMNS,
                                     STEP_KINDS, STEP_LOG, Site, StepRecord)
from workbench.session_validate import GAP_FACTOR, RATE_TOLERANCE, validate_parquet_stream, validate_samples
from workbench.values import ACCEL, GYRO, MAG, Unit

__all__ = ["ACCEL", "FLAG_REPEATED", "FLAG_SATURATED", "FORMAT", "GAP_FACTOR", "GYRO", "MAG", "OPTIONAL_COLUMNS",
           "RATE_TOLERANCE", "REQUIRED_COLUMNS", "STEP_KINDS", "STEP_LOG", "Session", "Site", "StepRecord", "Unit",
           "load_session", "parse_manifest", "read_manifest", "read_samples", "recorded_steps", "samples_file",
           "step_log", "validate_parquet_stream", "validate_samples", "write_manifest", "write_session"]


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
    data = read_manifest(directory)
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
