"""Retention by size, events closed after a crash, and snapshot writes the disk refuses."""

from __future__ import annotations

import errno
import sqlite3
from pathlib import Path

import cv2
import numpy as np
import pytest

from app.storage import Database, SnapshotStore, prune_to_size, write_atomic
from app.storage.engine import Target
from app.storage.files import describe_write_error
from tests.storage.conftest import raw_rows


def _jpeg(seed: int, side: int) -> bytes:
    """A real JPEG; noise makes its size grow with ``side``."""
    pixels = np.random.default_rng(seed).integers(0, 256, (side, side, 3), dtype=np.uint8)
    ok, data = cv2.imencode(".jpg", pixels, [cv2.IMWRITE_JPEG_QUALITY, 90])
    assert ok
    return data.tobytes()


def _bytes_on_disk(db: Database, store: SnapshotStore) -> int:
    return sum(store.path(s["path"]).stat().st_size for s in db.snapshots(limit=10_000))


def test_running_total_follows_inserts_and_deletes_and_survives_reopen(
    tmp_path: Path, db_target: Target
) -> None:
    db = Database(db_target)
    ids = [db.add_snapshot(1, None, float(i), "frame", f"1/{i}.jpg", 1000 + i) for i in range(5)]
    assert db.snapshot_bytes() == sum(1000 + i for i in range(5))
    db.delete_snapshots(ids[:2])
    db.close()
    again = Database(db_target)
    assert again.snapshot_bytes() == 1002 + 1003 + 1004
    assert raw_rows(db_target, "SELECT SUM(size) FROM snapshots") == [(1002 + 1003 + 1004,)]
    again.close()


def test_running_total_is_counted_for_a_database_from_before_it(tmp_path: Path) -> None:
    path = tmp_path / "old.db"
    old = sqlite3.connect(path)
    old.execute(
        "CREATE TABLE snapshots (id INTEGER PRIMARY KEY AUTOINCREMENT, camera_id INTEGER"
        " NOT NULL, event_id INTEGER, ts REAL NOT NULL, kind TEXT NOT NULL DEFAULT 'frame',"
        " path TEXT NOT NULL, size INTEGER NOT NULL DEFAULT 0)"
    )
    old.executemany(
        "INSERT INTO snapshots (camera_id, ts, path, size) VALUES (1, ?, ?, ?)",
        [(float(i), f"1/{i}.jpg", 500) for i in range(4)],
    )
    old.commit()
    old.close()
    db = Database(path)
    assert db.snapshot_bytes() == 2000
    db.add_snapshot(1, None, 9.0, "frame", "1/9.jpg", 250)
    assert db.snapshot_bytes() == 2250
    db.close()
    assert Database(path).snapshot_bytes() == 2250, "reopening must not count twice"


def test_size_cap_removes_the_oldest_snapshots_then_their_ended_events(
    tmp_path: Path, db_target: Target
) -> None:
    db = Database(db_target)
    store = SnapshotStore(tmp_path / "snaps")
    gone_event = db.add_event(1, 100.0, [], 1.0)  # Both its snapshots are the oldest.
    db.end_event(gone_event, 102.0, 1.0)
    split_event = db.add_event(1, 110.0, [], 1.0)  # Loses one of two.
    db.end_event(split_event, 112.0, 1.0)
    open_event = db.add_event(2, 105.0, [], 1.0)  # Still moving: kept without pictures.
    bare_event = db.add_event(2, 50.0, [], 1.0)  # Never had a snapshot (disk was full).
    db.end_event(bare_event, 51.0, 1.0)
    plan = [
        (gone_event, 100.0),
        (gone_event, 101.0),
        (open_event, 105.0),
        (split_event, 110.0),
        (split_event, 111.0),
        (None, 120.0),
        (None, 130.0),
    ]
    rows = []
    for i, (event, ts) in enumerate(plan):
        data = _jpeg(i, 64 + 8 * i)
        relative = store.save(1, ts, "frame", data, event)
        rows.append((db.add_snapshot(1, event, ts, "frame", relative, len(data)), relative, data))
    assert db.snapshot_bytes() == _bytes_on_disk(db, store)
    sizes = [len(data) for _, _, data in rows]
    cap = sum(sizes[4:]) + sizes[3] // 2  # Room for the newest three and half of the fourth.

    assert prune_to_size(db, store, cap, batch=2) == 4

    kept = [r for r in rows if db.snapshot(r[0]) is not None]
    assert [r[0] for r in kept] == [r[0] for r in rows[4:]], "the oldest go first, no more"
    for _, relative, _data in rows[:4]:
        assert not store.path(relative).exists()
    for _, relative, data in kept:
        assert store.path(relative).read_bytes() == data
    assert db.snapshot_bytes() == _bytes_on_disk(db, store) <= cap
    events = {e["id"] for e in db.events()}
    assert events == {split_event, open_event, bare_event}
    assert prune_to_size(db, store, cap) == 0, "under the cap nothing more goes"
    db.close()


def test_events_left_open_by_a_crash_end_at_their_last_snapshot(
    tmp_path: Path, db_target: Target
) -> None:
    db = Database(db_target)
    with_pictures = db.add_event(1, 100.0, [], 1.0)
    db.add_snapshot(1, with_pictures, 100.0, "frame", "a.jpg", 1)
    db.add_snapshot(1, with_pictures, 103.5, "frame", "b.jpg", 1)
    without = db.add_event(1, 200.0, [], 1.0)
    finished = db.add_event(1, 300.0, [], 1.0)
    db.end_event(finished, 310.0, 1.0)
    db.close()  # As a killed server leaves it.

    again = Database(db_target)
    assert len(again.close_open_events()) == 2
    ended = {e["id"]: e["ended_at"] for e in again.events()}
    assert ended == {with_pictures: 103.5, without: 200.0, finished: 310.0}
    assert again.close_open_events() == []
    again.close()


def _block_with_a_file(store: SnapshotStore, camera_id: int) -> Path:
    """A regular file where the camera's folder goes: mkdir fails, even for root."""
    blocker = store.root / str(camera_id)
    blocker.write_bytes(b"")
    return blocker


def test_a_refused_snapshot_write_is_remembered_per_camera_until_one_succeeds(
    tmp_path: Path,
) -> None:
    store = SnapshotStore(tmp_path / "snaps")
    blocker = _block_with_a_file(store, 7)
    with pytest.raises(OSError):
        store.save(7, 1000.0, "frame", b"jpeg", 1)
    reason = store.failure(7)
    assert reason and "/" not in reason, "a short reason, no path"
    assert store.failure(8) is None
    store.save(8, 1000.0, "frame", b"other", 2)  # Another camera's folder is fine.
    assert store.failure(7) == reason and store.failure(8) is None

    blocker.unlink()
    relative = store.save(7, 1001.0, "frame", b"jpeg", 3)
    assert store.path(relative).read_bytes() == b"jpeg"
    assert store.failure(7) is None


def test_write_errors_read_as_people_say_them() -> None:
    assert describe_write_error(OSError(errno.ENOSPC, "No space left on device")) == "disk full"
    assert describe_write_error(OSError(errno.EROFS, "x")) == "read-only file system"
    assert describe_write_error(OSError(errno.EDQUOT, "x")) == "disk quota exceeded"
    assert describe_write_error(OSError(errno.ENOTDIR, "Not a directory")) == (
        "cannot write (Not a directory)"
    )


def test_a_failed_durable_write_leaves_no_temporary_and_the_old_file(tmp_path: Path) -> None:
    target = tmp_path / "x.jpg"
    write_atomic(target, b"old", durable=True)
    in_the_way = tmp_path / "y.jpg"
    in_the_way.mkdir()  # Renaming a file over a folder fails.
    with pytest.raises(OSError):
        write_atomic(in_the_way, b"new", durable=True)
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.jpg", "y.jpg"]
