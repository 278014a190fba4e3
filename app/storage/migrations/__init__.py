"""The database's migrations, with Alembic: ``versions/`` holds one file per change of the
schema, each for SQLite and PostgreSQL alike, and ``app.storage.migrate`` runs them at start.

A change of schema is a new file in ``versions/`` (``python -m app.storage.migrations revision
-m "what"`` writes one from ``script.py.mako``, numbered after the last) and the same change
to the tables in ``app/storage/schema.py``; tests/storage/test_migrations.py checks that
both agree on both databases. Migrations only go forward: a release never goes back to an
older schema.
"""
