"""The store's tables and schema revision (workbench/store_schema.py): the migrations build what the tables declare."""

from __future__ import annotations

import pytest
from sqlalchemy import create_engine, inspect, text

from workbench.errors import StoreError
from workbench.store_schema import HEAD_REVISION, VERSION_TABLE, METADATA, schema_revision, upgrade


def test_empty_database_has_no_revision_and_upgrade_reaches_head(tmp_path):
    engine = create_engine(f"sqlite:///{tmp_path / 's.db'}")
    assert schema_revision(engine) is None
    assert upgrade(engine) == HEAD_REVISION
    assert schema_revision(engine) == HEAD_REVISION


def test_migrations_build_every_declared_table_and_column(tmp_path):
    engine = create_engine(f"sqlite:///{tmp_path / 's.db'}")
    upgrade(engine)
    insp = inspect(engine)
    assert set(METADATA.tables) <= set(insp.get_table_names())
    for name, table in METADATA.tables.items():
        built = {c["name"] for c in insp.get_columns(name)}
        assert built == {c.name for c in table.columns}, name


def test_several_heads_are_refused_with_the_fix(tmp_path):
    engine = create_engine(f"sqlite:///{tmp_path / 's.db'}")
    upgrade(engine)
    with engine.begin() as conn:
        conn.execute(text(f"INSERT INTO {VERSION_TABLE} (version_num) VALUES ('9999')"))
    with pytest.raises(StoreError, match="several schema revisions .*workbench db upgrade"):
        schema_revision(engine)
