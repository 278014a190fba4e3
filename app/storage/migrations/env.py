"""Alembic's environment: migrations run on the connection ``app.storage.migrate`` gives, in
the transaction it holds (and has locked against every other process); never offline."""

from __future__ import annotations

from alembic import context

from app.storage.schema import metadata

connection = context.config.attributes.get("connection")
if connection is None or context.is_offline_mode():
    raise RuntimeError("migrations run through app.storage.migrate, on a connection")
# render_as_batch: a generated change to a table is written as SQLite can make it (a copy
# of the table), which PostgreSQL runs as plain ALTER TABLE.
context.configure(connection=connection, target_metadata=metadata, render_as_batch=True)
with context.begin_transaction():  # Within the caller's transaction: commits with it.
    context.run_migrations()
