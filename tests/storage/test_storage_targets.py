"""Notification targets in SQLite: a database from before them gains the table; targets
round-trip; one URL is one target; ``VIGIL_NOTIFY_URLS``' targets follow the variable."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from app.storage import Database
from app.storage.db import IntegrityError
from app.storage.engine import Target


def test_a_database_from_before_notifications_gains_the_targets_table(tmp_path: Path) -> None:
    path = tmp_path / "old.db"
    db = Database(path)
    cam = db.add_camera("cam", "demo", "adaptive", 100.0)
    db.close()
    old = sqlite3.connect(path)  # As a release before notifications left it.
    old.execute("DROP INDEX notification_targets_url")
    old.execute("DROP TABLE notification_targets")
    old.execute("DROP TABLE alembic_version")  # Nor had it migrations,
    old.execute("DROP TABLE nodes")  # nor nodes.
    old.execute("DROP TABLE file_deletions")
    for table, column in [("cameras", c) for c in ("node", "lease_until", "pinned_to")] + [
        ("events", "node"),
        ("snapshots", "node"),
        ("analyses", "node"),
    ]:
        old.execute(f"ALTER TABLE {table} DROP COLUMN {column}")
    old.commit()
    old.close()

    db = Database(path)
    assert [c["id"] for c in db.cameras()] == [cam]
    assert db.targets() == []
    first = db.add_target("ntfys://door", None)
    second = db.add_target("json://host/hook", [cam, 9])
    db.close()
    again = Database(path)
    listed = again.targets()
    assert [(t["id"], t["url"], t["cameras"], t["origin"]) for t in listed] == [
        (first, "ntfys://door", None, "api"),
        (second, "json://host/hook", [cam, 9], "api"),
    ]
    assert again.target(second) == listed[1] and again.target(2**70) is None
    with pytest.raises(IntegrityError):
        again.add_target("ntfys://door", [cam])
    assert again.delete_target(first) and not again.delete_target(first)
    assert not again.delete_target(2**70)
    assert [t["id"] for t in again.targets()] == [second]
    again.close()


def test_targets_of_notify_urls_follow_the_variable(tmp_path: Path, db_target: Target) -> None:
    db = Database(db_target)
    mine = db.add_target("json://host/mine", None)
    assert db.sync_env_targets(["ntfys://a", "json://host/mine", "ntfys://b", "ntfys://a"]) == (
        2,
        0,
    )
    listed = {t["url"]: t for t in db.targets()}
    assert {u: t["origin"] for u, t in listed.items()} == {
        "json://host/mine": "api",  # Already a target: stays the user's.
        "ntfys://a": "env",
        "ntfys://b": "env",
    }
    # Started again with one of them gone: it goes, the other keeps its id.
    assert db.sync_env_targets(["ntfys://b"]) == (0, 1)
    assert [(t["id"], t["url"]) for t in db.targets()] == [
        (mine, "json://host/mine"),
        (listed["ntfys://b"]["id"], "ntfys://b"),
    ]
    assert db.sync_env_targets([]) == (0, 1)
    assert [t["url"] for t in db.targets()] == ["json://host/mine"]
    db.close()
