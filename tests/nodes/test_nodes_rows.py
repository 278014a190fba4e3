"""Files of rows deleted on one node that another node holds (app/storage/db.py's
``_hand_over``): on a real PostgreSQL, every way a row with a file goes (snapshots deleted,
events deleted, old events pruned, a clip dropped by the size cap) hands the file to the
node that made it, in the same transaction; that node takes each once, and no other node
is handed anything. Alone (SQLite) nothing is handed over. And a node starting fails only
the analyses it was running, not another node's."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from app.storage import Database


@pytest.fixture
def site(postgres_url: str) -> Iterator[tuple[Database, Database]]:
    """The databases of south and north, two nodes of a site on a real PostgreSQL."""
    south = Database(postgres_url, node="south")
    north = Database(postgres_url, migrate=False, node="north")
    yield south, north
    north.close()
    south.close()


def _event_with_files(db: Database, camera: int, started: float) -> tuple[int, list[str], str]:
    """An ended event with two snapshots and a finished clip: its id, snapshot and clip paths."""
    event = db.add_event(camera, started, [[1, 2, 3, 4]], 12.0)
    paths = [f"{camera}/day/{event}-{kind}.jpg" for kind in ("frame", "diff")]
    for path, kind in zip(paths, ("frame", "diff"), strict=True):
        db.add_snapshot(camera, event, started, kind, path, 100)
    clip = f"{camera}/day/{event}.mp4"
    db.start_clip(event, clip, started)
    db.end_event(event, started + 1, 12.0)
    assert db.finish_clip(event, 1000, 1.0)
    return event, paths, clip


def test_the_files_of_rows_deleted_elsewhere_go_to_the_node_that_holds_them(
    site: tuple[Database, Database],
) -> None:
    south, north = site
    camera = south.add_camera("door", "demo", "adaptive", 100.0)
    now = time.time()
    deleted, deleted_shots, deleted_clip = _event_with_files(south, camera, now)
    dropped, _, dropped_clip = _event_with_files(south, camera, now)
    pruned, pruned_shots, pruned_clip = _event_with_files(south, camera, now - 90 * 86400)
    own, own_shots, _ = _event_with_files(north, camera, now - 90 * 86400)  # North's.

    north.delete_snapshots(south.snapshot_ids_of([deleted]))
    north.delete_events([deleted])
    north.drop_clip(dropped, "deleted to stay under VIGIL_RETENTION_MB")
    north.delete_snapshots(south.snapshot_ids_of([pruned]))
    north.delete_snapshots(north.snapshot_ids_of([own]))
    north.delete_events_before(now - 86400)

    handed = south.take_file_deletions()
    assert sorted(handed) == sorted(
        [("snapshot", p) for p in deleted_shots + pruned_shots]
        + [("clip", deleted_clip), ("clip", dropped_clip), ("clip", pruned_clip)]
    )
    assert south.take_file_deletions() == []  # Each once.
    assert north.take_file_deletions() == []  # North deleted its own files itself.
    assert not any(path in own_shots for _, path in handed)


def test_alone_nothing_is_handed_over(tmp_path: Path) -> None:
    db = Database(tmp_path / "v.db", node="here")
    try:
        camera = db.add_camera("door", "demo", "adaptive", 100.0)
        event, _, _ = _event_with_files(db, camera, time.time())
        other = Database(tmp_path / "v.db", migrate=False, node="renamed")  # A new host name.
        other.delete_snapshots(db.snapshot_ids_of([event]))
        other.delete_events([event])
        assert db.take_file_deletions() == []
        other.close()
    finally:
        db.close()


def test_a_node_starting_fails_its_own_unfinished_analyses_not_another_nodes(
    site: tuple[Database, Database],
) -> None:
    south, north = site
    south.add_analysis("a1", "south.avi", {})
    south.update_analysis("a1", status="running")
    north.add_analysis("a2", "north.avi", {})
    assert north.fail_unfinished_analyses("the server stopped before it finished") == 1
    assert [(a["id"], a["status"]) for a in north.analyses()] == [
        ("a2", "failed"),
        ("a1", "running"),
    ]
