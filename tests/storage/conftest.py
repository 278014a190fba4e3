"""The storage tests run on both databases (``db_target``, in tests/conftest.py)."""

from __future__ import annotations

import contextlib
import sqlite3
from pathlib import Path

import psycopg

from app.storage.engine import Target


def raw_rows(target: Target, sql: str) -> list[tuple[object, ...]]:
    """``sql``'s rows read through a connection of the database's own driver, not Vigil's."""
    if isinstance(target, Path):
        with contextlib.closing(sqlite3.connect(target)) as conn:
            return conn.execute(sql).fetchall()
    with psycopg.connect(target) as pg:
        return pg.execute(sql).fetchall()  # type: ignore[arg-type]
