"""``workbench db``: the store's schema revision and its migrations (Alembic)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import typer

from workbench.cli import out
from workbench.errors import StoreError

db_app = typer.Typer(no_args_is_help=True, help="Store schema: current revision and upgrade.")


def _engine():
    from sqlalchemy import create_engine, inspect

    from workbench.store import default_url, redact_url

    real = default_url()
    url = redact_url(real)  # the password never appears in output
    with _store_errors(url, real, "cannot open"):
        engine = create_engine(real)
        inspect(engine).get_table_names()  # reads the file: a SQLite 'store' that is no database fails here
    return url, engine


@contextmanager
def _store_errors(url: str, real: str, doing: str) -> Iterator[None]:
    """A database library's error inside the block as one StoreError line naming the store (password redacted)."""
    from sqlalchemy.exc import SQLAlchemyError

    from workbench.store import redact

    try:
        yield
    except (SQLAlchemyError, ValueError, ImportError) as exc:
        raise StoreError(f"store {url}: {doing} ({redact(str(exc).splitlines()[0][:160], real)})") from None


@db_app.command("current")
def current() -> None:
    """Print the store's schema revision and the one this version needs."""
    from workbench.store import HEAD_REVISION, schema_revision

    url, engine = _engine()
    out.print(f"{url}: revision {schema_revision(engine) or 'none (empty)'}; this version needs {HEAD_REVISION}")


@db_app.command("upgrade")
def upgrade_cmd() -> None:
    """Migrate the store's schema to the revision this version needs."""
    from workbench.store import default_url, upgrade

    url, engine = _engine()
    with _store_errors(url, default_url(), "cannot upgrade"):
        revision = upgrade(engine)
    out.print(f"{url}: upgraded to revision {revision}")


def register(app: typer.Typer) -> None:
    app.add_typer(db_app, name="db")
