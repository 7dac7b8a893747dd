"""The store's tables (SQLAlchemy ORM) and their schema revision (Alembic, ``workbench/migrations``).

:class:`Base` and one row class per table (:class:`UnitRow`, :class:`SetRow`,
:class:`ApprovalRow`, :class:`SessionRow`, :class:`ResultRow`); :data:`HEAD_REVISION` (the
revision this code expects), :func:`schema_revision` (read from Alembic's version table
without loading Alembic) and :func:`upgrade`. Text columns hold canonical JSON; times are
ISO-8601 UTC strings. :class:`workbench.store.Store` reads and writes them.
"""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import Boolean, ForeignKey, Integer, String, Text, UniqueConstraint, create_engine, inspect, text
from sqlalchemy.engine import Engine
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column

from workbench.errors import StoreError

HEAD_REVISION = "0001"  # the Alembic revision this version of the code expects
VERSION_TABLE = "alembic_version"  # where Alembic keeps the schema revision
MIGRATIONS = Path(__file__).resolve().parent / "migrations"


class Base(DeclarativeBase):
    """The declarative base of the store's tables."""


class UnitRow(Base):
    """A unit under test: serial, model, first seen (ISO-8601 UTC)."""

    __tablename__ = "units"
    serial: Mapped[str] = mapped_column(String(128), primary_key=True)
    model: Mapped[str] = mapped_column(String(128), default="")
    created: Mapped[str] = mapped_column(String(40))


class SetRow(Base):
    """A stored calibration set: id, unit, version per serial, procedures, SHA-256 and canonical JSON body."""

    __tablename__ = "calibration_sets"
    __table_args__ = (UniqueConstraint("serial", "version", name="uq_set_serial_version"),)
    id: Mapped[str] = mapped_column(String(64), primary_key=True)
    serial: Mapped[str] = mapped_column(ForeignKey("units.serial"), index=True)
    version: Mapped[int] = mapped_column(Integer)
    created: Mapped[str] = mapped_column(String(40))
    procedures: Mapped[str] = mapped_column(Text)  # comma-separated, for listing
    sha256: Mapped[str] = mapped_column(String(64))
    body: Mapped[str] = mapped_column(Text)  # canonical JSON


class ApprovalRow(Base):
    """The approval of a set: by whom, when, comment."""

    __tablename__ = "approvals"
    set_id: Mapped[str] = mapped_column(ForeignKey("calibration_sets.id"), primary_key=True)
    approved_by: Mapped[str] = mapped_column(String(128))
    approved_at: Mapped[str] = mapped_column(String(40))
    comment: Mapped[str] = mapped_column(Text, default="")


class SessionRow(Base):
    """A recorded session: id, unit, procedure, folder, samples SHA-256, step count, complete or not."""

    __tablename__ = "sessions"
    id: Mapped[str] = mapped_column(String(64), primary_key=True)
    serial: Mapped[str] = mapped_column(ForeignKey("units.serial"), index=True)
    procedure: Mapped[str] = mapped_column(String(64))
    path: Mapped[str] = mapped_column(Text)
    created: Mapped[str] = mapped_column(String(40))
    sha256: Mapped[str] = mapped_column(String(64), default="")
    n_steps: Mapped[int] = mapped_column(Integer, default=0)
    complete: Mapped[bool] = mapped_column(Boolean, default=True)


class ResultRow(Base):
    """An analysis result: procedure, session, unit, calibration set id, result.json body."""

    __tablename__ = "results"
    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    procedure: Mapped[str] = mapped_column(String(64), index=True)
    session_id: Mapped[str] = mapped_column(String(64), index=True)
    serial: Mapped[str] = mapped_column(String(128), index=True)
    calibration_id: Mapped[str | None] = mapped_column(String(64), nullable=True)
    created: Mapped[str] = mapped_column(String(40))
    body: Mapped[str] = mapped_column(Text)


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
