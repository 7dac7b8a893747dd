"""``workbench db``: the store's schema revision and its migrations (Alembic)."""

from __future__ import annotations

import typer

from workbench.cli import out
from workbench.errors import StoreError

db_app = typer.Typer(no_args_is_help=True, help="Store schema: current revision and upgrade.")


def _engine():
    from sqlalchemy import create_engine
    from sqlalchemy.exc import SQLAlchemyError

    from workbench.store import default_url, redact, redact_url

    real = default_url()
    url = redact_url(real)  # the password never appears in output
    try:
        engine = create_engine(real)
        engine.connect().close()
    except (SQLAlchemyError, ValueError, ImportError) as exc:
        raise StoreError(f"store {url}: cannot open ({redact(str(exc).splitlines()[0][:160], real)})") from None
    return url, engine


@db_app.command("current")
def current() -> None:
    """Print the store's schema revision and the one this version needs."""
    from workbench.store import HEAD_REVISION, schema_revision

    url, engine = _engine()
    out.print(f"{url}: revision {schema_revision(engine) or 'none (empty)'}; this version needs {HEAD_REVISION}")


@db_app.command("upgrade")
def upgrade_cmd() -> None:
    """Migrate the store's schema to the revision this version needs."""
    from workbench.store import upgrade

    url, engine = _engine()
    out.print(f"{url}: upgraded to revision {upgrade(engine)}")


def register(app: typer.Typer) -> None:
    app.add_typer(db_app, name="db")
