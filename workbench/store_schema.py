"""The store's tables (SQLAlchemy Core) and their schema revision (Alembic, ``workbench/migrations``).

:data:`METADATA` and one :class:`~sqlalchemy.Table` per table (:data:`UNITS`, :data:`SETS`,
:data:`APPROVALS`, :data:`SESSIONS`, :data:`RESULTS`); :data:`HEAD_REVISION` (the revision this
code expects), :func:`schema_revision` (read from Alembic's version table without loading
Alembic) and :func:`upgrade`. Text columns hold canonical JSON; times are ISO-8601 UTC strings.
:class:`workbench.store.Store` reads and writes them. Core tables, not ORM classes: the store
reads and writes whole rows by key, and ``sqlalchemy.orm`` would add about 0.1 s to every
command that opens the store (``workbench sets list``, issue 23).
"""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import (Boolean, Column, ForeignKey, Integer, MetaData, String, Table, Text, UniqueConstraint,
                        create_engine, inspect, text)
from sqlalchemy.engine import Engine

from workbench.errors import StoreError
from workbench.store_read import HEAD_REVISION, VERSION_TABLE  # noqa: F401 - the revision, read without SQLAlchemy too
MIGRATIONS = Path(__file__).resolve().parent / "migrations"

METADATA = MetaData()

UNITS = Table(  # a unit under test: serial, model, first seen (ISO-8601 UTC)
    "units", METADATA,
    Column("serial", String(128), primary_key=True),
    Column("model", String(128), nullable=False, default=""),
    Column("created", String(40), nullable=False))

SETS = Table(  # a stored calibration set: id, unit, version per serial, procedures, SHA-256, canonical JSON
    "calibration_sets", METADATA,
    Column("id", String(64), primary_key=True),
    Column("serial", String(128), ForeignKey("units.serial"), nullable=False, index=True),
    Column("version", Integer, nullable=False),
    Column("created", String(40), nullable=False),
    Column("procedures", Text, nullable=False),  # comma-separated, for listing
    Column("sha256", String(64), nullable=False),
    Column("body", Text, nullable=False),  # canonical JSON
    UniqueConstraint("serial", "version", name="uq_set_serial_version"))

APPROVALS = Table(  # the approval of a set: by whom, when, comment
    "approvals", METADATA,
    Column("set_id", String(64), ForeignKey("calibration_sets.id"), primary_key=True),
    Column("approved_by", String(128), nullable=False),
    Column("approved_at", String(40), nullable=False),
    Column("comment", Text, nullable=False, default=""))

SESSIONS = Table(  # a recorded session: id, unit, procedure, folder, samples SHA-256, step count, complete or not
    "sessions", METADATA,
    Column("id", String(64), primary_key=True),
    Column("serial", String(128), ForeignKey("units.serial"), nullable=False, index=True),
    Column("procedure", String(64), nullable=False),
    Column("path", Text, nullable=False),
    Column("created", String(40), nullable=False),
    Column("sha256", String(64), nullable=False, default=""),
    Column("n_steps", Integer, nullable=False, default=0),
    Column("complete", Boolean, nullable=False, default=True))

RESULTS = Table(  # an analysis result: procedure, session, unit, calibration set id, result.json body
    "results", METADATA,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("procedure", String(64), nullable=False, index=True),
    Column("session_id", String(64), nullable=False, index=True),
    Column("serial", String(128), nullable=False, index=True),
    Column("calibration_id", String(64), nullable=True),
    Column("created", String(40), nullable=False),
    Column("body", Text, nullable=False))


def _alembic_config(connection):
    from alembic.config import Config

    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS))
    cfg.attributes["connection"] = connection
    return cfg


def schema_revision(engine: Engine) -> str | None:
    """The Alembic revision of the database's schema (None for an empty database).

    Read from Alembic's version table directly: opening the store does not load Alembic.
    """
    with engine.connect() as conn:
        if not inspect(conn).has_table(VERSION_TABLE):
            return None
        heads = conn.execute(text(f"SELECT version_num FROM {VERSION_TABLE}")).scalars().all()
    if len(heads) > 1:
        raise StoreError(f"store {engine.url}: several schema revisions ({', '.join(heads)}); "
                         f"run `workbench db upgrade`")
    return heads[0] if heads else None


def upgrade(engine_or_url: Engine | str, revision: str = "head") -> str | None:
    """Migrate the database to ``revision`` (Alembic); returns the revision reached."""
    from alembic import command

    engine = create_engine(engine_or_url) if isinstance(engine_or_url, str) else engine_or_url
    with engine.begin() as conn:
        command.upgrade(_alembic_config(conn), revision)
    return schema_revision(engine)
