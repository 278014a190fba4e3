"""SQLite in WAL mode, snapshot files written whole, the zip streamed in pieces."""

from __future__ import annotations

import io
import sqlite3
import sys
import threading
import zipfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from app.storage import Database, SnapshotStore, stream_zip, write_atomic
from app.storage.db import DatabaseClosedError
from app.storage.engine import Target
from tests.storage.conftest import raw_rows


def test_database_is_wal_and_cameras_round_trip(tmp_path: Path, db_target: Target) -> None:
    db = Database(db_target)
    assert db.journal_mode == ("wal" if isinstance(db_target, Path) else "")
    cam = db.add_camera("door", "file:///x.avi", "adaptive", 100.0)
    db.update_camera(cam, sensitivity=40.0, active=1, show_mask=1)
    db.close()
    again = Database(db_target)
    (row,) = again.cameras()
    assert row["name"] == "door" and row["sensitivity"] == 40.0
    assert row["active"] is True and row["show_mask"] is True
    assert again.delete_camera(cam) and again.cameras() == []
    again.close()


def test_of_nodes_starting_together_into_an_empty_database_one_adds_the_demo(
    db_target: Target,
) -> None:
    """Four processes (here: four Database objects, their own connections) at the same
    moment, again and again: one demo camera each time, never two; none once there is one."""
    nodes = [Database(db_target) for _ in range(4)]
    start = threading.Barrier(len(nodes))

    def add(db: Database) -> int | None:
        start.wait(10)
        return db.add_first_camera("demo", "demo", "adaptive", 100.0)

    with ThreadPoolExecutor(len(nodes)) as pool:
        for _ in range(30):
            added = [i for i in pool.map(add, nodes) if i is not None]
            assert len(added) == 1 and [c["id"] for c in nodes[0].cameras()] == added
            assert nodes[1].add_first_camera("demo", "demo", "adaptive", 100.0) is None
            nodes[2].delete_camera(added[0])
    for db in nodes:
        db.close()


def test_a_closed_database_refuses_to_be_used(db_target: Target) -> None:
    db = Database(db_target)
    camera = db.add_camera("a", "demo", "adaptive", 100.0)
    db.close()
    with pytest.raises(DatabaseClosedError):
        db.camera(camera)
    with pytest.raises(DatabaseClosedError):
        db.add_event(camera, 1.0, [], 1.0)


def test_other_connections_read_while_open(tmp_path: Path, db_target: Target) -> None:
    db = Database(db_target)
    db.add_camera("a", "demo", "adaptive", 100.0)
    assert raw_rows(db_target, "SELECT name FROM cameras") == [("a",)]
    db.close()


def test_events_and_snapshot_filters(tmp_path: Path, db_target: Target) -> None:
    db = Database(db_target)
    e1 = db.add_event(1, 100.0, [[1, 2, 3, 4]], 12.0, [1])
    db.add_event(2, 200.0, [], 5.0)
    db.end_event(e1, 101.5, 30.0, [1, 2])
    (ev,) = db.events(camera_id=1)
    assert ev["ended_at"] == 101.5 and ev["max_area"] == 30.0 and ev["track_ids"] == [1, 2]
    assert [e["camera_id"] for e in db.events(since=150)] == [2]
    s1 = db.add_snapshot(1, e1, 100.0, "frame", "1/a.jpg", 10)
    db.add_snapshot(1, e1, 100.0, "difference", "1/b.jpg", 10)
    db.add_snapshot(2, None, 300.0, "frame", "2/c.jpg", 10)
    assert len(db.snapshots(camera_id=1)) == 2
    assert len(db.snapshots(kind="frame")) == 2
    assert [s["camera_id"] for s in db.snapshots(since=250)] == [2]
    assert [s["id"] for s in db.snapshots(until=150, kind="frame")] == [s1]
    assert [r["id"] for r in db.delete_snapshots([s1, 999])] == [s1]
    assert db.snapshot(s1) is None
    db.close()


def test_long_lists_and_limits_fit_what_each_database_takes(db_target: Target) -> None:
    """More ids than one statement may hold (SQLite: 32766, psycopg: 65535), and a limit
    beyond PostgreSQL's 32-bit LIMIT, as the API and the benches ask."""
    db = Database(db_target)
    ids = [db.add_snapshot(1, None, float(i % 7), "frame", f"{i}.jpg", 1) for i in range(1200)]
    asked = [*range(-5, 70_000), 2**70]
    found = db.snapshots(ids=asked, limit=100_000)
    assert [s["id"] for s in found] == sorted(ids, key=lambda i: ((i - 1) % 7, i), reverse=True)
    assert [s["id"] for s in db.snapshots(ids=asked, limit=3)] == [s["id"] for s in found[:3]]
    assert len(db.snapshots(limit=sys.maxsize)) == 1200 == len(db.oldest_snapshots(2**40))
    assert db.events(limit=sys.maxsize) == [] and db.analyses(limit=sys.maxsize) == []
    assert len(db.delete_snapshots(asked)) == 1200 and db.snapshot_bytes() == 0
    db.close()


def test_event_filters_select_events_that_overlap_the_window(
    tmp_path: Path, db_target: Target
) -> None:
    """``since``/``until`` select the events going on at some time in the window: one that
    began before ``since`` and ended (or is still running) after it is in."""
    db = Database(db_target)
    early = db.add_event(1, 50.0, [], 1.0)
    db.end_event(early, 60.0, 1.0)
    across = db.add_event(1, 100.0, [], 1.0)
    db.end_event(across, 110.0, 1.0)
    running = db.add_event(2, 200.0, [], 1.0)  # Open: it runs on.

    def ids(**window: float) -> list[int]:
        return [e["id"] for e in db.events(**window)]  # type: ignore[arg-type]

    assert ids(since=105) == [running, across]
    assert ids(since=105, until=150) == [across]
    assert ids(until=105) == [across, early]
    assert ids(since=60.5, until=99.5) == []
    assert ids(since=1e9) == [running]
    assert ids(since=60, until=100) == [across, early]  # The ends of the window count.
    assert [e["id"] for e in db.events(camera_id=1, since=105)] == [across]
    assert ids(since=105, until=100) == [], "a window that ends before it starts holds none"
    db.close()


def test_unfinished_analyses_fail_on_restart(tmp_path: Path, db_target: Target) -> None:
    db = Database(db_target)
    db.add_analysis("abc", "x.avi", {"method": None})
    db.add_analysis("def", "y.avi", {})
    db.update_analysis("def", status="done", progress=1.0)
    assert db.fail_unfinished_analyses("restarted") == 1
    assert db.analysis("abc")["status"] == "failed"  # type: ignore[index]
    assert db.analysis("abc")["error"] == "restarted"  # type: ignore[index]
    assert db.analysis("def")["status"] == "done"  # type: ignore[index]
    db.close()


def test_write_atomic_leaves_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "deep" / "x.jpg"
    write_atomic(target, b"one")
    write_atomic(target, b"two")
    assert target.read_bytes() == b"two"
    assert [p.name for p in target.parent.iterdir()] == ["x.jpg"]


def test_snapshot_store_paths_stay_inside(tmp_path: Path) -> None:
    store = SnapshotStore(tmp_path / "snaps")
    relative = store.save(3, 1_700_000_000.25, "frame", b"jpeg", 9)
    assert relative.startswith("3/2023-11-14/") and relative.endswith("-e9-frame.jpg")
    assert store.path(relative).read_bytes() == b"jpeg"
    try:
        store.path("../../etc/passwd")
    except ValueError:
        pass
    else:
        raise AssertionError("a path outside the store was accepted")


def test_stream_zip_is_streamed_and_valid(tmp_path: Path) -> None:
    files = []
    for i in range(5):
        path = tmp_path / f"{i}.jpg"
        path.write_bytes(bytes([i]) * (100_000 + i))
        files.append((path, f"cam/{i}.jpg"))
    files.append((tmp_path / "missing.jpg", "cam/missing.jpg"))
    chunks = list(stream_zip(files, chunk_size=16_384))
    assert len(chunks) > 5, "the zip should come in pieces, not whole"
    archive = zipfile.ZipFile(io.BytesIO(b"".join(chunks)))
    assert archive.testzip() is None
    assert archive.namelist() == [f"cam/{i}.jpg" for i in range(5)]
    assert archive.read("cam/3.jpg") == bytes([3]) * 100_003


def test_prune_removes_old_snapshots_and_events(tmp_path: Path, db_target: Target) -> None:
    from app.storage import prune

    db = Database(db_target)
    store = SnapshotStore(tmp_path / "snaps")
    old_event = db.add_event(1, 100.0, [], 1.0)
    db.end_event(old_event, 101.0, 1.0)
    open_event = db.add_event(1, 150.0, [], 1.0)
    new_event = db.add_event(1, 5000.0, [], 1.0)
    old = store.save(1, 100.0, "frame", b"a", old_event)
    new = store.save(1, 5000.0, "frame", b"b", new_event)
    db.add_snapshot(1, old_event, 100.0, "frame", old, 1)
    keep = db.add_snapshot(1, new_event, 5000.0, "frame", new, 1)
    assert prune(db, store, before=1000.0, batch=1) == 1
    assert [s["id"] for s in db.snapshots()] == [keep]
    assert not store.path(old).exists() and store.path(new).exists()
    assert sorted(e["id"] for e in db.events()) == [open_event, new_event]
    db.close()


def test_a_database_from_before_ignore_zones_gains_the_column(tmp_path: Path) -> None:
    path = tmp_path / "old.db"
    old = sqlite3.connect(path)
    old.execute(
        "CREATE TABLE cameras (id INTEGER PRIMARY KEY AUTOINCREMENT, name TEXT NOT NULL,"
        " source TEXT NOT NULL, sensitivity REAL, min_area REAL NOT NULL DEFAULT 100,"
        " method TEXT NOT NULL, show_mask INTEGER NOT NULL DEFAULT 0,"
        " active INTEGER NOT NULL DEFAULT 0, created_at REAL NOT NULL)"
    )
    old.execute(
        "INSERT INTO cameras (name, source, method, created_at)"
        " VALUES ('cam', 'demo', 'adaptive', 0)"
    )
    old.commit()
    old.close()
    db = Database(path)
    (camera,) = db.cameras()
    assert camera["name"] == "cam" and camera["mask"] == []
