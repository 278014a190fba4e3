"""Migrations at start: the server brings the schema up to this release's before anything
else uses the database; camera processes only check that it has.

One process migrates at a time. On PostgreSQL the migration holds an advisory lock for its
transaction (``pg_advisory_xact_lock``): a second server starting at once (another node)
waits for it, then finds the schema up to date and does nothing. On SQLite the migration's
transaction holds the write lock from its start (``BEGIN IMMEDIATE``) to the same effect.
Either way the whole migration is one transaction: interrupted, it leaves the schema as it
was (both databases make and alter tables transactionally).

``python -m app.storage.migrations revision -m "what"`` writes a new, empty migration into
``app/storage/migrations/versions/`` (for developers; see that package's docstring).
"""

from __future__ import annotations

import functools
import logging
import time
from pathlib import Path

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Connection, Engine, text

from app.storage import engine as engines

log = logging.getLogger("vigil.storage")
# Alembic tells of each look at the schema at INFO; our own line says when one migrates.
logging.getLogger("alembic").setLevel(logging.WARNING)

MIGRATIONS = Path(__file__).with_name("migrations")
LOCK_KEY = 0x76696769  # "vigi": the advisory lock that one migration at a time holds.
MIGRATE_TIMEOUT_S = 120.0
"""How long a SQLite migration waits for another process's write (or migration)."""
CHECK_TIMEOUT_S = 60.0
"""How long a camera process waits for the server to finish migrating."""


class SchemaError(RuntimeError):
    """The database's schema is not this release's, and this process cannot make it so."""


def config() -> Config:
    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS))
    cfg.set_main_option("path_separator", "os")
    return cfg


@functools.cache
def head() -> str:
    """This release's schema: the last migration's revision."""
    found = ScriptDirectory.from_config(config()).get_current_head()
    assert found is not None, "no migration found"
    return found


@functools.cache
def known() -> frozenset[str]:
    return frozenset(s.revision for s in ScriptDirectory.from_config(config()).walk_revisions())


def revision(conn: Connection) -> str | None:
    """The schema's revision in the database (None: none yet, or SQLite from before
    migrations)."""
    return MigrationContext.configure(conn).get_current_revision()


def upgrade(target: engines.Target) -> tuple[str | None, str]:
    """Bring the database at ``target`` up to ``head()``; the revisions before and after.

    SchemaError if it was migrated by a newer release (a revision this one does not know).
    """
    engine = engines.create(target, busy_timeout_s=MIGRATE_TIMEOUT_S)
    try:
        with engines.writer(engine).begin() as conn:
            if conn.dialect.name == engines.POSTGRESQL:
                conn.execute(text("SELECT pg_advisory_xact_lock(:key)"), {"key": LOCK_KEY})
            before = revision(conn)
            _check_known(before)
            if before != head():
                cfg = config()
                cfg.attributes["connection"] = conn
                command.upgrade(cfg, "head")
    finally:
        engine.dispose()
    if before != head():
        log.info("database: schema migrated from %s to %s", before or "none", head())
    return before, head()


def wait_for_head(engine: Engine, timeout_s: float | None = None) -> None:
    """Return once the database's schema is ``head()`` (the server migrates it at start);
    SchemaError if it is not within ``timeout_s`` (``CHECK_TIMEOUT_S``), or is newer than
    this release's."""
    deadline = time.monotonic() + (CHECK_TIMEOUT_S if timeout_s is None else timeout_s)
    while True:
        with engines.reader(engine).connect() as conn:
            current = revision(conn)
        if current == head():
            return
        _check_known(current)
        if time.monotonic() > deadline:
            raise SchemaError(
                f"the database's schema is at {current or 'none'}, not {head()}:"
                " `vigil serve` migrates it at start"
            )
        time.sleep(0.25)


def _check_known(current: str | None) -> None:
    if current is not None and current not in known():
        raise SchemaError(
            f"the database's schema ({current}) is newer than this Vigil's ({head()}):"
            " a newer release has migrated it; upgrade this one"
        )
