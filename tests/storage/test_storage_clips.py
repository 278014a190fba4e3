"""Clips in the database and on disk: their running total, retention by size and by age with
snapshots, a database from before clips, and clips a killed process left unfinished."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import cv2
import numpy as np
import pytest
from sqlalchemy import update

from app.recording.mp4 import ClipFrame, H264Writer
from app.storage import ClipStore, Database, SnapshotStore, prune, prune_to_size
from app.storage.clips import KILLED, clip_length_s, finish_unfinished
from app.storage.engine import Target
from app.storage.files import RETENTION
from app.storage.schema import events
from tests.api.vigil_livekit import FPS, frame_at


def _clip(store: ClipStore, db: Database, event_id: int, seconds: float = 1.0) -> str:
    """A real clip of ``seconds`` for the event, finished as a recorder finishes one."""
    row = db.event(event_id)
    assert row is not None
    relative, path = store.create(row["camera_id"], row["started_at"], event_id)
    db.start_clip(event_id, relative, row["started_at"] - 1)
    with path.open("wb", buffering=0) as file:
        writer = H264Writer(file, FPS)
        for i in range(round(seconds * FPS)):
            jpeg = cv2.imencode(".jpg", frame_at(i % 45))[1].tobytes()
            writer.write(ClipFrame(i / FPS, 0.0, (320, 240), jpeg=jpeg), i / FPS)
        writer.close()
    db.finish_clip(event_id, path.stat().st_size, writer.length_s)
    return relative


def _ended(db: Database, camera_id: int, started_at: float) -> int:
    event = db.add_event(camera_id, started_at, [], 1.0)
    db.end_event(event, started_at + 1, 1.0)
    return event


def test_the_clips_total_follows_their_rows_and_survives_reopen(
    tmp_path: Path, db_target: Target
) -> None:
    db = Database(db_target)
    first, second = _ended(db, 1, 100.0), _ended(db, 1, 200.0)
    db.start_clip(first, "1/a.mp4", 99.0)
    db.finish_clip(first, 5000, 3.0)
    db.start_clip(second, "1/b.mp4", 199.0)
    db.finish_clip(second, 7000, 4.0)
    assert db.clip_bytes() == 12000
    db.drop_clip(first, "gone")
    assert db.clip_bytes() == 7000
    db.delete_events([second])
    db.close()
    again = Database(db_target)
    assert again.clip_bytes() == 0
    again.close()


def test_a_database_from_before_clips_gains_them(tmp_path: Path) -> None:
    path = tmp_path / "old.db"
    old = sqlite3.connect(path)
    old.execute(
        "CREATE TABLE events (id INTEGER PRIMARY KEY AUTOINCREMENT, camera_id INTEGER NOT NULL,"
        " started_at REAL NOT NULL, ended_at REAL, max_area REAL NOT NULL DEFAULT 0,"
        " boxes TEXT NOT NULL DEFAULT '[]', track_ids TEXT NOT NULL DEFAULT '[]')"
    )
    old.execute("INSERT INTO events (camera_id, started_at, ended_at) VALUES (1, 5.0, 6.0)")
    old.commit()
    old.close()
    db = Database(path)
    (event,) = db.events()
    assert event["clip_path"] is None and event["clip_bytes"] == 0 and db.clip_bytes() == 0
    db.start_clip(event["id"], "1/x.mp4", 4.0)
    db.finish_clip(event["id"], 300, 1.0)
    db.close()
    assert Database(path).clip_bytes() == 300, "reopening must not count twice"


def test_the_size_cap_takes_the_oldest_snapshots_and_clips_alike(
    tmp_path: Path, db_target: Target
) -> None:
    db = Database(db_target)
    snapshots = SnapshotStore(tmp_path / "snaps")
    clips = ClipStore(tmp_path / "clips")
    oldest = _ended(db, 1, 100.0)  # A clip and a snapshot: both go, and so does it.
    middle = _ended(db, 1, 200.0)  # Its clip goes; its later snapshot stays, and so does it.
    newest = _ended(db, 1, 300.0)
    recording = db.add_event(1, 50.0, [], 1.0)  # Oldest of all, but its clip is recording.
    db.start_clip(recording, "1/rec.mp4", 49.0)
    for event in (oldest, middle, newest):
        _clip(clips, db, event)
    jpeg = cv2.imencode(".jpg", np.full((64, 64, 3), 90, np.uint8))[1].tobytes()
    for event, ts in ((oldest, 100.5), (middle, 250.0), (newest, 300.5)):
        relative = snapshots.save(1, ts, "frame", jpeg, event)
        db.add_snapshot(1, event, ts, "frame", relative, len(jpeg))
    sizes = {e: db.event(e)["clip_bytes"] for e in (oldest, middle, newest)}  # type: ignore[index]
    total = db.snapshot_bytes() + db.clip_bytes()
    assert total == 3 * len(jpeg) + sum(sizes.values())
    cap = total - sizes[oldest] - len(jpeg) - sizes[middle] // 2

    assert prune_to_size(db, snapshots, cap, clips=clips) == 3

    assert db.event(oldest) is None, "its clip and snapshot gone, it goes"
    kept = db.event(middle)
    assert kept is not None and kept["clip_path"] is None and kept["clip_error"] == RETENTION
    assert db.event(newest)["clip_path"] is not None  # type: ignore[index]
    assert db.event(recording)["clip_path"] == "1/rec.mp4"  # type: ignore[index]
    assert db.snapshot_bytes() + db.clip_bytes() <= cap
    on_disk = sum(p.stat().st_size for p in clips.root.rglob("*.mp4"))
    assert on_disk == db.clip_bytes() == sizes[newest]
    assert prune_to_size(db, snapshots, cap, clips=clips) == 0


def test_age_takes_old_events_with_their_clips_and_activity(
    tmp_path: Path, db_target: Target
) -> None:
    db = Database(db_target)
    snapshots = SnapshotStore(tmp_path / "snaps")
    clips = ClipStore(tmp_path / "clips")
    old, new = _ended(db, 1, 100.0), _ended(db, 2, 2000.0)
    old_clip, new_clip = _clip(clips, db, old), _clip(clips, db, new)
    db.add_activity(1, [(100, 0.5), (1500, 0.2)])
    db.add_activity(2, [(900, 0.1), (2000, 0.3)])
    assert prune(db, snapshots, before=1000.0, clips=clips) == 1
    assert db.event(old) is None and not clips.path(old_clip).exists()
    assert db.event(new) is not None and clips.path(new_clip).exists()
    assert db.activity(1, 0, 3000, 3000) == {0: (0.2, 0)}
    assert db.activity(2, 0, 3000, 3000) == {0: (0.3, 1)}


def test_clips_a_kill_left_unfinished_are_cut_to_what_plays(
    tmp_path: Path, db_target: Target
) -> None:
    db = Database(db_target)
    clips = ClipStore(tmp_path / "clips")
    cut, empty, gone = (_ended(db, 1, t) for t in (100.0, 200.0, 300.0))
    relative = _clip(clips, db, cut, seconds=4.0)
    data = clips.path(relative).read_bytes()
    clips.path(relative).write_bytes(data[: len(data) * 2 // 3])
    _clip(clips, db, empty)
    clips.path(db.event(empty)["clip_path"]).write_bytes(data[:100])  # type: ignore[index]
    db.start_clip(gone, "1/never-written.mp4", 299.0)
    for event in (cut, empty):  # As a killed recorder leaves them: no length yet.
        with db.transaction() as conn:
            conn.execute(
                update(events).where(events.c.id == event).values(clip_s=None, clip_bytes=0)
            )
    db.close()

    again = Database(db_target)
    assert finish_unfinished(again, clips) == 3
    row = again.event(cut)
    assert row is not None and row["clip_error"] == KILLED
    assert 1.0 <= row["clip_s"] <= 3.0
    assert row["clip_s"] == pytest.approx(clip_length_s(clips.path(relative)))
    assert row["clip_bytes"] == clips.path(relative).stat().st_size == again.clip_bytes()
    for event in (empty, gone):
        dropped = again.event(event)
        assert dropped is not None and dropped["clip_path"] is None
        assert dropped["clip_error"] == KILLED
    assert again.unfinished_clips() == []
    assert finish_unfinished(again, clips) == 0


def test_a_node_finishes_only_the_unfinished_clips_on_its_own_disk(
    tmp_path: Path, db_target: Target
) -> None:
    """A node that takes over a dead node's camera cannot reach that node's disk: the clip
    it was recording stays as it is, for its own node to finish when it is back."""
    north, south = Database(db_target, node="north"), Database(db_target, node="south")
    theirs = _ended(north, 1, 100.0)
    north.start_clip(theirs, "1/north.mp4", 99.0)  # Killed while recording it.
    ours = _ended(south, 1, 200.0)
    south.start_clip(ours, "1/south-never-written.mp4", 199.0)

    assert finish_unfinished(south, ClipStore(tmp_path / "south")) == 1
    assert south.event(ours)["clip_error"] == KILLED  # type: ignore[index]
    assert [e["id"] for e in south.unfinished_clips()] == []
    assert [e["id"] for e in north.unfinished_clips()] == [theirs]
    north.close()
    south.close()
