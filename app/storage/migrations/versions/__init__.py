"""One file per change of the schema, oldest first (Alembic reads them, not Python's import)."""
