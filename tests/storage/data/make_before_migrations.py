"""Writes ``before_migrations.db``: a database as Vigil wrote it before migrations (the
release whose app/storage/db.py made its schema at every start, commit 239966a), with rows
in every table, for tests/storage/test_migrations.py to upgrade.

Run it in a checkout of that release, with only that release's ``app`` importable::

    git worktree add /tmp/before 239966a
    cd /tmp/before && python -P /path/to/make_before_migrations.py /path/to/before_migrations.db
"""

from __future__ import annotations

import sqlite3
import sys
from pathlib import Path

sys.path.insert(0, str(Path.cwd()))

from app.storage import Database  # The release's own, from the current folder.


def main(out: Path) -> None:
    out.unlink(missing_ok=True)
    db = Database(out)
    assert not hasattr(db, "engine"), "run this with the release from before migrations"
    door = db.add_camera("door", "rtsp://admin:secret@10.0.0.5/stream", "adaptive", 150.0, 40.0)
    yard = db.add_camera("yard", "demo", "frame-difference", 100.0)
    db.update_camera(door, active=1, show_mask=1, mask=[[[0, 0], [10, 0], [10, 10]]])
    ended = db.add_event(door, 1_700_000_000.25, [[1, 2, 30, 40]], 120.0, [1])
    db.end_event(ended, 1_700_000_004.5, 300.0, [2, 1])
    db.start_clip(ended, "1/2023-11-14/221320250-e1.mp4", 1_700_000_000.0)
    db.finish_clip(ended, 48_213, 6.5)
    recording = db.add_event(door, 1_700_000_100.0, [], 10.0)
    db.end_event(recording, 1_700_000_101.0, 10.0)
    db.start_clip(recording, "1/2023-11-14/221500000-e2.mp4", 1_700_000_099.0)
    dropped = db.add_event(yard, 1_700_000_200.0, [[5, 5, 5, 5]], 25.0, [7])
    db.end_event(dropped, 1_700_000_201.0, 25.0, [7])
    db.start_clip(dropped, "2/2023-11-14/221640000-e3.mp4", 1_700_000_199.0)
    db.drop_clip(dropped, "disk full")
    db.add_event(yard, 1_700_000_300.0, [[9, 9, 9, 9]], 81.0, [8])  # Still open.
    for event, ts, kind, size in (
        (ended, 1_700_000_000.25, "frame", 20_480),
        (ended, 1_700_000_000.25, "difference", 3_100),
        (ended, 1_700_000_002.0, "frame", 20_101),
        (dropped, 1_700_000_200.0, "frame", 18_000),
        (None, 1_700_000_250.0, "frame", 17_777),
    ):
        db.add_snapshot(door if event != dropped else yard, event, ts, kind, f"x/{size}.jpg", size)
    db.add_activity(door, [(1_700_000_000, 0.25), (1_700_000_001, 0.5), (1_700_000_100, 0.01)])
    db.add_activity(yard, [(1_700_000_200, 0.125)])
    db.add_analysis("a1", "clip.avi", {"method": "adaptive", "sensitivity": None})
    db.update_analysis("a1", status="done", progress=1.0, finished_at=1_700_000_500.0)
    db.add_analysis("a2", "other.mp4", {})
    db.add_target("json://hooks.example/vigil", [door])
    db.sync_env_targets(["ntfys://vigil-door"])
    db.close()
    with sqlite3.connect(out) as conn:  # One file: the WAL checkpointed and gone.
        conn.execute("VACUUM")
    conn.close()
    assert not Path(f"{out}-wal").exists()


if __name__ == "__main__":
    main(Path(sys.argv[1]).resolve())
