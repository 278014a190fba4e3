"""The storage tests run on both databases: ``db_target`` is where a fresh one is, a SQLite
file or a PostgreSQL database of its own (skipped where PostgreSQL cannot be run)."""

from __future__ import annotations

import contextlib
import sqlite3
from pathlib import Path

import psycopg
import pytest

from app.storage.engine import Target


@pytest.fixture(params=["sqlite", "postgresql"])
def db_target(request: pytest.FixtureRequest, tmp_path: Path) -> Target:
    if request.param == "sqlite":
        return tmp_path / "v.db"
    url: str = request.getfixturevalue("postgres_url")
    return url


def raw_rows(target: Target, sql: str) -> list[tuple[object, ...]]:
    """``sql``'s rows read through a connection of the database's own driver, not Vigil's."""
    if isinstance(target, Path):
        with contextlib.closing(sqlite3.connect(target)) as conn:
            return conn.execute(sql).fetchall()
    with psycopg.connect(target) as pg:
        return pg.execute(sql).fetchall()  # type: ignore[arg-type]
