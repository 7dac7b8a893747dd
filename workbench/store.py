"""The store: units, calibration sets, sessions and analysis results in a SQL database.

SQLAlchemy 2 over any URL; the embedded default is SQLite at ``./workbench.db``
(``--db`` / ``WORKBENCH_DB`` override it). A stored calibration set is never modified: a new
calibration of a unit is a new version (1, 2, ... per serial). Every write is one
transaction (or part of one ``Store.batch()``), so a failed or interrupted write leaves the
store as it was. SQLite writers
take the database lock up front (``BEGIN IMMEDIATE``) so concurrent processes queue
instead of failing mid-transaction. The tables and their schema revision are
:mod:`workbench.store_schema`.
"""

from __future__ import annotations

import hashlib
import json
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

from sqlalchemy import create_engine, event, func, insert, inspect, select, text, update
from sqlalchemy.engine import Connection, Engine
from sqlalchemy.exc import IntegrityError, OperationalError, SQLAlchemyError

from workbench.errors import StoreError
from workbench.store_read import (DEFAULT_URL, SetInfo, default_url, list_sets_sql, redact,  # noqa: F401 (re-exported)
                                  redact_url, set_infos)
from workbench.store_schema import (APPROVALS, HEAD_REVISION, METADATA, MIGRATIONS, RESULTS,  # noqa: F401 (re-exported)
                                    SESSIONS, SETS, UNITS, VERSION_TABLE, schema_revision, upgrade)

if TYPE_CHECKING:  # the calibration-set format (numpy, jsonschema) loads when a set is read
    from workbench.calset import CalibrationSet


class StoreConflict(StoreError):
    """A transaction rolled back because another writer took the same key (e.g. a set version)."""


@dataclass(frozen=True)
class SessionInfo:
    """One recorded session: id, unit serial, procedure, folder, created (ISO-8601 UTC), samples
    SHA-256, step count and whether it is complete."""

    id: str
    serial: str
    procedure: str
    path: str
    created: str
    sha256: str
    n_steps: int
    complete: bool


def _now() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def _set_from_row(set_id: str, body: str) -> CalibrationSet:
    """The calibration set a stored row (id, canonical JSON body) holds; a set stored before the id /
    serial / model rules is read (its ``name_problems()`` say what it breaks; storing or exporting it again
    is refused)."""
    from workbench.calset import CalibrationSet

    return CalibrationSet.from_json(body, source=f"store set {set_id}", names=False)


def _next_version(db: Connection, serial: str) -> int:
    """The version number the next set of unit ``serial`` gets (1 for its first)."""
    return (db.scalar(select(func.max(SETS.c.version)).where(SETS.c.serial == serial)) or 0) + 1


def _sqlite_immediate(engine: Engine) -> None:
    @event.listens_for(engine, "connect")
    def _connect(dbapi_conn, _record):
        dbapi_conn.isolation_level = None  # let SQLAlchemy's BEGIN below take effect
        dbapi_conn.execute("PRAGMA busy_timeout = 30000")
        dbapi_conn.execute("PRAGMA journal_mode = WAL")

    @event.listens_for(engine, "begin")
    def _begin(conn):
        conn.exec_driver_sql("BEGIN IMMEDIATE")


class Store:
    """Calibration sets, units, sessions and results in one database (see module docstring)."""

    def __init__(self, url: str | None = None, create: bool = True):
        real = url or default_url()
        self.url, self._real = redact_url(real), real  # messages and output show .url: never the password
        try:
            self.engine = create_engine(real)
        except (SQLAlchemyError, ValueError, ImportError) as exc:
            raise StoreError(f"store {self.url}: cannot open ({redact(str(exc).splitlines()[0][:160], real)})"
                             ) from None
        if self.engine.dialect.name == "sqlite":
            db = self.engine.url.database
            if db and db != ":memory:" and not Path(db).parent.resolve().is_dir():
                raise StoreError(f"store {self.url}: folder {Path(db).parent} does not exist")
            _sqlite_immediate(self.engine)
        self._batch = threading.local()  # .db: the open transaction of batch() in this thread
        if create:
            self._create_schema()

    def _create_schema(self) -> None:
        """Create the schema in an empty database; refuse one at an older revision."""
        try:
            current = schema_revision(self.engine)
            if current is None and not inspect(self.engine).get_table_names():
                upgrade(self.engine)
            elif current != HEAD_REVISION:
                raise StoreError(f"store {self.url}: schema revision {current or 'unknown'}, this version needs "
                                 f"{HEAD_REVISION}; run `workbench db upgrade --db {self.url}`")
        except SQLAlchemyError as exc:
            raise StoreError(f"store {self.url}: cannot open ({redact(str(exc).splitlines()[0][:160], self._real)})"
                             ) from None

    @contextmanager
    def transaction(self) -> Iterator[Connection]:
        """One all-or-nothing transaction; errors become StoreError naming the store.

        Inside :meth:`batch` (same thread) this is the batch's transaction.
        """
        if self._in_batch():
            yield self._batch.db
            return
        try:
            with self.engine.begin() as db:
                yield db
        except IntegrityError:
            raise
        except OperationalError as exc:
            raise StoreError(f"store {self.url}: {redact(str(exc.orig)[:160], self._real)}") from None

    @contextmanager
    def batch(self) -> Iterator[None]:
        """Make the writes inside one transaction (one commit for many small writes), all or nothing.

        A version conflict with another writer is not retried inside: the whole batch is rolled
        back and raises StoreError, and the caller writes the items again (one by one).
        """
        if self._in_batch():
            yield
            return
        try:
            with self.transaction() as db:
                self._batch.db = db
                try:
                    yield
                finally:
                    self._batch.db = None
        except IntegrityError as exc:
            raise StoreConflict(f"store {self.url}: batch rolled back, another writer conflicts "
                                f"({str(exc.orig).splitlines()[0][:120]})") from None

    def write_together(self, write: Callable[[], object], retries: int = 20) -> object:
        """Run ``write`` (several store writes) as one transaction: all of it is stored or none.

        One command = one transaction (a session record, its results and its calibration set).
        When another writer took the unit's next set version the whole transaction is rolled
        back and run again.
        """
        for attempt in range(retries - 1):
            try:
                with self.batch():
                    return write()
            except StoreConflict:
                if self._in_batch():
                    raise
                time.sleep(0.05 * (attempt + 1))
        with self.batch():
            return write()

    def _in_batch(self) -> bool:
        return getattr(self._batch, "db", None) is not None

    def _ensure_unit(self, db: Connection, serial: str, model: str) -> None:
        known = db.execute(select(UNITS.c.model).where(UNITS.c.serial == serial)).first()
        if known is None:
            db.execute(insert(UNITS).values(serial=serial, model=model, created=_now()))
        elif model and not known.model:
            db.execute(update(UNITS).where(UNITS.c.serial == serial).values(model=model))

    def _insert_set(self, db: Connection, calset: CalibrationSet, body: str, sha256: str) -> int:
        """Insert ``calset`` (its canonical JSON ``body``) as its unit's next version; returns the version."""
        version = _next_version(db, calset.unit.serial)
        db.execute(insert(SETS).values(id=calset.id, serial=calset.unit.serial, version=version,
                                       created=calset.created, procedures=",".join(calset.provenance.procedures),
                                       sha256=sha256, body=body))
        return version

    # -- calibration sets ------------------------------------------------------------
    def add_set(self, calset: CalibrationSet, retries: int = 20) -> int:
        """Store a set as the next version of its unit; returns the version number."""
        body = calset.to_json()
        for attempt in range(retries):
            try:
                with self.transaction() as db:
                    if db.scalar(select(SETS.c.id).where(SETS.c.id == calset.id)) is not None:
                        raise StoreError(f"store {self.url}: set {calset.id} is already stored (sets are immutable)")
                    self._ensure_unit(db, calset.unit.serial, calset.unit.model)
                    version = self._insert_set(db, calset, body, calset.sha256())
                return version
            except IntegrityError:
                if self._in_batch():
                    raise  # batch() rolls back and reports; its caller writes again
                time.sleep(0.05 * (attempt + 1))  # another writer took this version number
        raise StoreError(f"store {self.url}: could not allocate a version for {calset.unit.serial}")

    def get_set(self, set_id: str) -> CalibrationSet:
        """The stored set ``set_id`` (a unique prefix of the id is accepted)."""
        with self.transaction() as db:
            row = db.execute(select(SETS.c.id, SETS.c.body).where(SETS.c.id == set_id)).first()
            if row is None:
                rows = db.execute(select(SETS.c.id, SETS.c.body).where(SETS.c.id.like(f"{set_id}%"))).all()
                if len(rows) != 1:
                    what = "matches several sets" if rows else "is not in the store"
                    raise StoreError(f"store {self.url}: set {set_id!r} {what}")
                row = rows[0]
        return _set_from_row(row.id, row.body)

    def latest(self, serial: str) -> CalibrationSet | None:
        """The newest set of unit ``serial`` (None if it has none)."""
        with self.transaction() as db:
            row = db.execute(select(SETS.c.id, SETS.c.body).where(SETS.c.serial == serial)
                             .order_by(SETS.c.version.desc())).first()
        return None if row is None else _set_from_row(row.id, row.body)

    def list_sets(self, serial: str | None = None) -> list[SetInfo]:
        """Stored sets (all, or one unit's history), newest first (the query of :mod:`workbench.store_read`)."""
        with self.transaction() as db:
            rows = db.execute(text(list_sets_sql(serial)), {"serial": serial} if serial is not None else {}).all()
        return set_infos(rows)

    def history(self, serial: str) -> list[SetInfo]:
        """All versions of one unit's calibration, newest first."""
        return self.list_sets(serial)

    def approve(self, set_id: str, by: str, comment: str = "") -> None:
        """Record that ``by`` approved set ``set_id`` (the set itself is not modified). ``by`` is a name
        (one printable line, not blank: a blank approver listed as 'approved by —' looked unapproved),
        ``comment`` one printable line; StoreError otherwise."""
        from workbench.confine import plain_line

        if not isinstance(by, str) or not by.strip():
            raise StoreError(f"store {self.url}: approve {set_id}: the approver's name is blank")
        plain_line(by, "approver", StoreError)
        plain_line(comment, "approval comment", StoreError)
        full_id = self.get_set(set_id).id
        with self.transaction() as db:
            if db.scalar(select(APPROVALS.c.set_id).where(APPROVALS.c.set_id == full_id)) is not None:
                raise StoreError(f"store {self.url}: set {full_id} is already approved")
            db.execute(insert(APPROVALS).values(set_id=full_id, approved_by=by, approved_at=_now(), comment=comment))

    def approval(self, set_id: str) -> dict | None:
        """The approval of a stored set (``approved_by``, ``approved_at`` UTC, ``comment``), None if not approved."""
        with self.transaction() as db:
            row = db.execute(select(APPROVALS.c.approved_by, APPROVALS.c.approved_at, APPROVALS.c.comment)
                             .where(APPROVALS.c.set_id == set_id)).first()
        return None if row is None else dict(row._mapping)

    def units(self) -> list[tuple[str, str]]:
        """(serial, model) of every unit in the store."""
        with self.transaction() as db:
            return [(u.serial, u.model) for u in db.execute(select(UNITS.c.serial, UNITS.c.model)
                                                            .order_by(UNITS.c.serial))]

    # -- sessions and results --------------------------------------------------------
    def add_session(self, session_id: str, serial: str, model: str, procedure: str, path: str,
                    sha256: str = "", n_steps: int = 0, complete: bool = True) -> None:
        """Record a session (or update its completeness when it is recorded again on resume)."""
        path = str(Path(path).resolve()) if path else ""
        with self.transaction() as db:
            self._ensure_unit(db, serial, model)
            if db.scalar(select(SESSIONS.c.id).where(SESSIONS.c.id == session_id)) is None:
                db.execute(insert(SESSIONS).values(id=session_id, serial=serial, procedure=procedure, path=path,
                                                   created=_now(), sha256=sha256, n_steps=n_steps, complete=complete))
            else:
                db.execute(update(SESSIONS).where(SESSIONS.c.id == session_id)
                           .values(sha256=sha256, n_steps=n_steps, complete=complete))

    def list_sessions(self, serial: str | None = None) -> list[SessionInfo]:
        """Recorded sessions, newest first."""
        with self.transaction() as db:
            q = select(SESSIONS)
            if serial is not None:
                q = q.where(SESSIONS.c.serial == serial)
            return [SessionInfo(**r._mapping) for r in db.execute(q.order_by(SESSIONS.c.created.desc()))]

    def add_result(self, procedure: str, session_id: str, serial: str, result: dict,
                   calset: CalibrationSet | None = None) -> int:
        """Store an analysis result (and its calibration set, in the same transaction)."""
        body = None if calset is None else calset.to_json()  # validates; serialised once for body and hash
        for attempt in range(20):
            try:
                with self.transaction() as db:
                    self._ensure_unit(db, serial, calset.unit.model if calset else "")
                    if calset is not None:
                        self._insert_set(db, calset, body, hashlib.sha256(body.encode()).hexdigest())
                    inserted = db.execute(insert(RESULTS).values(
                        procedure=procedure, session_id=session_id, serial=serial,
                        calibration_id=calset.id if calset else None, created=_now(), body=json.dumps(result)))
                    return inserted.inserted_primary_key[0]
            except IntegrityError:
                if self._in_batch():
                    raise
                time.sleep(0.05 * (attempt + 1))
        raise StoreError(f"store {self.url}: could not store the result of {procedure}")

    def list_results(self, procedure: str | None = None, serial: str | None = None) -> list[dict]:
        """Stored results as dicts (``id``, ``procedure``, ``session_id``, ``serial``, ``created``, ``result``)."""
        with self.transaction() as db:
            q = select(RESULTS)
            if procedure is not None:
                q = q.where(RESULTS.c.procedure == procedure)
            if serial is not None:
                q = q.where(RESULTS.c.serial == serial)
            return [{"id": r.id, "procedure": r.procedure, "session_id": r.session_id, "serial": r.serial,
                     "calibration_id": r.calibration_id, "created": r.created, "result": json.loads(r.body)}
                    for r in db.execute(q.order_by(RESULTS.c.id.desc()))]
