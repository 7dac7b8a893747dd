"""The store's URL and its set listing, without SQLAlchemy (what ``workbench sets list`` needs).

:func:`default_url`, :func:`redact_url` and :func:`redact` (the store URL and its password);
:data:`HEAD_REVISION` and :data:`VERSION_TABLE` (the schema revision this code expects and the
table Alembic keeps it in); :class:`SetInfo` (one line of a listing) and :func:`list_sets`.

The listing is one SQL text (:func:`list_sets_sql`, portable SQL over the tables of
:mod:`workbench.store_schema`): :meth:`workbench.store.Store.list_sets` runs it through
SQLAlchemy on any URL, and :func:`list_sets` runs the same text through Python's own
``sqlite3``, read-only, when the URL names an existing SQLite file at :data:`HEAD_REVISION`.
Anything else (a store to create, another database, an older revision, a file ``sqlite3``
cannot read) goes to :class:`~workbench.store.Store`, which creates, lists or refuses it with
its usual one-line messages. Importing SQLAlchemy costs a command about 0.15-0.3 s, half of
what ``sets list`` took (issue 23).
"""

from __future__ import annotations

import os
import re
import sqlite3
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

DEFAULT_URL = "sqlite:///workbench.db"
HEAD_REVISION = "0001"  # the Alembic revision this version of the code expects
VERSION_TABLE = "alembic_version"  # where Alembic keeps the schema revision
_PASSWORD = re.compile(r"^(?P<head>[^:/?#]+://[^:@/?#]*):(?P<password>[^@/?#]*)@")
_SQLITE_FILE = re.compile(r"sqlite(?:\+pysqlite)?:///(?P<path>[^?%]+)")  # a plain file URL, no query, no escapes


def default_url() -> str:
    """The store URL: ``WORKBENCH_DB`` if set, else SQLite ``./workbench.db``."""
    return os.environ.get("WORKBENCH_DB") or DEFAULT_URL


def redact_url(url: str) -> str:
    """``url`` with its password (``scheme://user:PASSWORD@host``) replaced by ``***``, for output."""
    return _PASSWORD.sub(r"\g<head>:***@", url, count=1)


def redact(text: str, url: str) -> str:
    """``text`` (e.g. a database driver's message) with ``url``'s password replaced by ``***``."""
    m = _PASSWORD.match(url)
    return text.replace(m["password"], "***") if m and m["password"] else text


@dataclass(frozen=True)
class SetInfo:
    """One line of a set listing."""

    id: str
    serial: str
    model: str
    version: int
    created: str
    procedures: tuple[str, ...]
    approved_by: str | None


def list_sets_sql(serial: str | None) -> str:
    """The listing query, newest first; with a ``serial``, one unit's sets (bound as ``:serial``)."""
    where = "WHERE s.serial = :serial " if serial is not None else ""
    return ("SELECT s.id, s.serial, u.model, s.version, s.created, s.procedures, a.approved_by "
            "FROM calibration_sets AS s JOIN units AS u ON u.serial = s.serial "
            f"LEFT OUTER JOIN approvals AS a ON a.set_id = s.id {where}"
            "ORDER BY s.created DESC, s.version DESC")


def set_infos(rows: Iterable[tuple]) -> list[SetInfo]:
    """Rows of :func:`list_sets_sql` as :class:`SetInfo`."""
    return [SetInfo(i, serial, model, int(version), created, tuple(p for p in procedures.split(",") if p), by)
            for i, serial, model, version, created, procedures, by in rows]


def _sqlite_rows(url: str, serial: str | None) -> list[tuple] | None:
    """The listing's rows read with ``sqlite3`` (read-only), or None when the store is not an
    existing SQLite file at :data:`HEAD_REVISION` that ``sqlite3`` can read."""
    m = _SQLITE_FILE.fullmatch(url)
    if m is None or m["path"] == ":memory:" or not Path(m["path"]).is_file():
        return None
    try:
        con = sqlite3.connect(f"{Path(m['path']).resolve().as_uri()}?mode=ro", uri=True, timeout=30)
        try:
            if [r[0] for r in con.execute(f"SELECT version_num FROM {VERSION_TABLE}")] != [HEAD_REVISION]:
                return None
            return con.execute(list_sets_sql(serial), {"serial": serial}).fetchall()
        finally:
            con.close()
    except sqlite3.Error:
        return None


def list_sets(serial: str | None = None, url: str | None = None) -> tuple[str, list[SetInfo]]:
    """(the store's URL for output, password redacted; its sets, all or unit ``serial``'s, newest first).

    ``url``: the store (default :func:`default_url`). Same rows as
    :meth:`workbench.store.Store.list_sets`, which answers (and creates or refuses the store) when
    this cannot read it without SQLAlchemy.
    """
    real = url or default_url()
    rows = _sqlite_rows(real, serial)
    if rows is None:
        from workbench.store import Store

        store = Store(real)
        return store.url, store.list_sets(serial)
    return redact_url(real), set_infos(rows)
