"""Alembic environment of the workbench store (run through ``workbench.store.upgrade``)."""

from alembic import context

from workbench.store_schema import METADATA

connection = context.config.attributes["connection"]
context.configure(connection=connection, target_metadata=METADATA, render_as_batch=True)
with context.begin_transaction():
    context.run_migrations()
