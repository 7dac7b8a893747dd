"""The store on SQLite and PostgreSQL: migrations from empty, concurrent writers, old schemas.

PostgreSQL tests run when WORKBENCH_TEST_POSTGRES holds a server URL (``.ci/run`` starts one
on 127.0.0.1); each test gets its own database, dropped afterwards.
"""

import os
import uuid

import pytest
from sqlalchemy import create_engine, text

from tests.core.test_store import a_set, run_writers
from workbench.errors import StoreError
from workbench.store import HEAD_REVISION, Store, schema_revision

PG = os.environ.get("WORKBENCH_TEST_POSTGRES")


@pytest.fixture(params=["sqlite", "postgresql"])
def url(request, tmp_path):
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path}/w.db"
        return
    if not PG:
        pytest.skip("WORKBENCH_TEST_POSTGRES is not set (no PostgreSQL server; .ci/run starts one)")
    name = f"wb_{uuid.uuid4().hex[:12]}"
    admin = create_engine(PG, isolation_level="AUTOCOMMIT")
    with admin.connect() as c:
        c.execute(text(f"CREATE DATABASE {name}"))
    yield PG.rsplit("/", 1)[0] + f"/{name}"
    with admin.connect() as c:
        c.execute(text(f"DROP DATABASE {name} WITH (FORCE)"))
    admin.dispose()


def test_migrates_an_empty_database_to_head(url):
    store = Store(url)
    assert schema_revision(store.engine) == HEAD_REVISION
    assert store.add_set(a_set()) == 1


def test_older_schema_is_refused_with_the_migration_command(url):
    engine = create_engine(url)
    with engine.begin() as c:
        c.execute(text("CREATE TABLE alembic_version (version_num VARCHAR(32) NOT NULL)"))
        c.execute(text("INSERT INTO alembic_version VALUES ('0000')"))
    with pytest.raises(StoreError, match="revision 0000.*workbench db upgrade"):
        Store(url)


def test_concurrent_writers_from_several_processes(url):
    Store(url)
    run_writers(url, 3, 10)
    assert sorted(i.version for i in Store(url).history("U1")) == list(range(1, 31))


def test_unreachable_database_is_a_clear_error():
    with pytest.raises(StoreError, match="cannot open"):
        Store("postgresql+psycopg://nobody@127.0.0.1:1/none")
