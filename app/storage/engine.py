"""Which database Vigil uses, and how each process connects to it.

Without ``VIGIL_DATABASE_URL``: SQLite, ``vigil.db`` in the data folder, as always. Each
process (the server, each camera process) has one connection, shared by its threads in
turn (a pool of one), in WAL mode with ``synchronous=FULL``: a committed event survives a
killed process and a power cut alike. Writes take the database's write lock at their start
(``BEGIN IMMEDIATE``) and wait up to ``BUSY_TIMEOUT_S`` for another process's; reads run
outside transactions, and WAL keeps them from waiting for writers.

With ``VIGIL_DATABASE_URL=postgresql://user:password@host:5432/database``: PostgreSQL
through psycopg 3, a small pool per process (``POOL_SIZE`` kept open, up to
``POOL_OVERFLOW`` more at busy moments), each connection tested before use so that a
database restarted meanwhile costs no request. Reads run in autocommit, writes in a
transaction (read committed).
"""

from __future__ import annotations

import sqlite3
from pathlib import Path

from sqlalchemy import URL, Engine, create_engine, event, make_url
from sqlalchemy.engine import Connection
from sqlalchemy.exc import ArgumentError
from sqlalchemy.pool import ConnectionPoolEntry, QueuePool

SQLITE = "sqlite"
POSTGRESQL = "postgresql"

BUSY_TIMEOUT_S = 5.0
"""How long a SQLite write waits for another process's before it fails."""
POOL_SIZE = 2
"""PostgreSQL connections each process keeps open."""
POOL_OVERFLOW = 3
"""More PostgreSQL connections a process may open while its threads all want one (closed
once returned); beyond them a thread waits for one, up to ``POOL_TIMEOUT_S``."""
POOL_TIMEOUT_S = 30.0
CONNECT_TIMEOUT_S = 10

POSTGRES_SCHEMES = frozenset({"postgresql", "postgres", "postgresql+psycopg"})
WRITE = "vigil_write"
"""The execution option of a connection whose transactions write (SQLite: ``BEGIN
IMMEDIATE``, the write lock at once, not at the first write, which could fail midway)."""

Target = Path | str
"""Where the database is: a SQLite file's path, or a PostgreSQL URL."""


def postgres_url(value: str) -> URL:
    """``VIGIL_DATABASE_URL`` as SQLAlchemy's URL for psycopg 3; ValueError when it is no
    PostgreSQL URL naming a database (the message never repeats the URL: its password)."""
    try:
        url = make_url(value.strip())
    except (ArgumentError, ValueError):
        raise ValueError(
            "not a database URL: postgresql://user:password@host:5432/database"
            " (a password's special characters %-encoded)"
        ) from None
    if url.drivername not in POSTGRES_SCHEMES:
        raise ValueError(f"{url.drivername}:// is not PostgreSQL: use postgresql://")
    if not url.database:
        raise ValueError("names no database: postgresql://user:password@host:5432/database")
    return url.set(drivername="postgresql+psycopg")


def shown(target: Target) -> str:
    """The database as logs show it: a file's path, or the URL without its password (nor
    a password among its parameters)."""
    if isinstance(target, Path):
        return str(target)
    url = postgres_url(target).set(drivername="postgresql")
    secret = {key for key in url.query if "password" in key.lower()}
    url = url.difference_update_query(secret)
    return url.render_as_string(hide_password=True)


def engine_name(target: Target) -> str:
    return SQLITE if isinstance(target, Path) else POSTGRESQL


def create(target: Target, busy_timeout_s: float = BUSY_TIMEOUT_S) -> Engine:
    """An engine for ``target``, set up as the module says."""
    if isinstance(target, Path):
        return _sqlite(target, busy_timeout_s)
    return create_engine(
        postgres_url(target),
        poolclass=QueuePool,
        pool_size=POOL_SIZE,
        max_overflow=POOL_OVERFLOW,
        pool_timeout=POOL_TIMEOUT_S,
        pool_pre_ping=True,
        hide_parameters=True,  # An error names no value: a camera's or a target's secrets.
        connect_args={"connect_timeout": CONNECT_TIMEOUT_S, "application_name": "vigil"},
    )


def _sqlite(path: Path, busy_timeout_s: float) -> Engine:
    path.parent.mkdir(parents=True, exist_ok=True)
    engine = create_engine(
        URL.create("sqlite", database=str(path)),
        poolclass=QueuePool,
        pool_size=1,  # One connection per process, its threads in turn, as a lock would.
        max_overflow=0,
        pool_timeout=POOL_TIMEOUT_S,
        hide_parameters=True,
        connect_args={"check_same_thread": False, "timeout": busy_timeout_s},
    )

    @event.listens_for(engine, "connect")
    def _connect(dbapi: sqlite3.Connection, _record: ConnectionPoolEntry) -> None:
        # The sqlite3 module's own transactions off: the "begin" below says when one starts.
        dbapi.isolation_level = None
        dbapi.execute("PRAGMA journal_mode=WAL")
        dbapi.execute("PRAGMA synchronous=FULL")
        dbapi.execute(f"PRAGMA busy_timeout={int(busy_timeout_s * 1000)}")

    @event.listens_for(engine, "begin")
    def _begin(conn: Connection) -> None:
        # A read runs outside any transaction (each statement on its own, as sqlite3 does).
        if conn.get_execution_options().get(WRITE):
            conn.exec_driver_sql("BEGIN IMMEDIATE")

    return engine


def writer(engine: Engine) -> Engine:
    """The same engine and pool, its transactions marked as writing."""
    return engine.execution_options(**{WRITE: True})


def reader(engine: Engine) -> Engine:
    """The same engine and pool for reads: autocommit on PostgreSQL (no BEGIN and ROLLBACK
    around each query); SQLite's reads already run outside transactions."""
    if engine.dialect.name == POSTGRESQL:
        return engine.execution_options(isolation_level="AUTOCOMMIT")
    return engine
