"""SQLite (stdlib sqlite3, WAL mode): cameras, events, snapshots, analyses and notification
targets.

One connection shared by every thread behind a lock: writes are small and
rare (an event, a snapshot, a setting), so a lock is simpler than a pool and
WAL keeps readers of other processes (a backup, ``sqlite3`` by hand) unblocked.

``synchronous=FULL``: a committed event survives a killed process and a power
cut alike. It costs one fsync per commit, and commits come per alarm, not per
frame.
"""

from __future__ import annotations

import json
import math
import sqlite3
import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

SCHEMA = """
CREATE TABLE IF NOT EXISTS cameras (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    name TEXT NOT NULL,
    source TEXT NOT NULL,
    sensitivity REAL,
    min_area REAL NOT NULL DEFAULT 100,
    method TEXT NOT NULL,
    show_mask INTEGER NOT NULL DEFAULT 0,
    active INTEGER NOT NULL DEFAULT 0,
    created_at REAL NOT NULL,
    mask TEXT NOT NULL DEFAULT '[]'
);
CREATE TABLE IF NOT EXISTS events (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    camera_id INTEGER NOT NULL,
    started_at REAL NOT NULL,
    ended_at REAL,
    max_area REAL NOT NULL DEFAULT 0,
    boxes TEXT NOT NULL DEFAULT '[]',
    track_ids TEXT NOT NULL DEFAULT '[]'
);
CREATE INDEX IF NOT EXISTS events_camera_time ON events (camera_id, started_at);
CREATE TABLE IF NOT EXISTS snapshots (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    camera_id INTEGER NOT NULL,
    event_id INTEGER,
    ts REAL NOT NULL,
    kind TEXT NOT NULL DEFAULT 'frame',
    path TEXT NOT NULL,
    size INTEGER NOT NULL DEFAULT 0
);
CREATE INDEX IF NOT EXISTS snapshots_camera_time ON snapshots (camera_id, ts);
CREATE INDEX IF NOT EXISTS snapshots_time ON snapshots (ts);
CREATE INDEX IF NOT EXISTS snapshots_event ON snapshots (event_id);
CREATE INDEX IF NOT EXISTS events_time ON events (started_at);
CREATE INDEX IF NOT EXISTS events_open ON events (camera_id) WHERE ended_at IS NULL;
-- The snapshots' total size, kept by triggers, so a size cap is checked without a scan.
CREATE TABLE IF NOT EXISTS snapshot_usage (
    id INTEGER PRIMARY KEY CHECK (id = 1),
    bytes INTEGER NOT NULL
);
INSERT OR IGNORE INTO snapshot_usage (id, bytes) SELECT 1, COALESCE(SUM(size), 0) FROM snapshots;
CREATE TRIGGER IF NOT EXISTS snapshot_usage_insert AFTER INSERT ON snapshots BEGIN
    UPDATE snapshot_usage SET bytes = bytes + NEW.size WHERE id = 1;
END;
CREATE TRIGGER IF NOT EXISTS snapshot_usage_delete AFTER DELETE ON snapshots BEGIN
    UPDATE snapshot_usage SET bytes = bytes - OLD.size WHERE id = 1;
END;
CREATE TABLE IF NOT EXISTS analyses (
    id TEXT PRIMARY KEY,
    filename TEXT NOT NULL,
    status TEXT NOT NULL,
    progress REAL NOT NULL DEFAULT 0,
    error TEXT,
    options TEXT NOT NULL DEFAULT '{}',
    created_at REAL NOT NULL,
    finished_at REAL
);
-- Where notifications go: Apprise URLs (app/notify). cameras: a JSON list of camera ids,
-- NULL for every camera. origin: 'api' (the API or the page) or 'env' (VIGIL_NOTIFY_URLS).
CREATE TABLE IF NOT EXISTS notification_targets (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    url TEXT NOT NULL,
    cameras TEXT,
    origin TEXT NOT NULL DEFAULT 'api',
    created_at REAL NOT NULL
);
CREATE UNIQUE INDEX IF NOT EXISTS notification_targets_url ON notification_targets (url);
"""

CAMERA_FIELDS = (
    "name",
    "source",
    "sensitivity",
    "min_area",
    "method",
    "show_mask",
    "active",
    "mask",
)
# Columns added after the first release, with their definitions, for older databases.
ADDED_CAMERA_COLUMNS = {"mask": "TEXT NOT NULL DEFAULT '[]'"}
ADDED_EVENT_COLUMNS = {
    # An event's clip (app/recording/): its file under the clips folder, null when it has
    # none (not recorded, refused by the disk, deleted by retention: clip_error says why).
    "clip_path": "TEXT",
    "clip_bytes": "INTEGER NOT NULL DEFAULT 0",
    "clip_s": "REAL",  # Null while the clip is being recorded.
    "clip_started_at": "REAL",  # The wall time of its first frame.
    "clip_error": "TEXT",
}
RECORDINGS_SCHEMA = """
CREATE INDEX IF NOT EXISTS events_clips ON events (started_at) WHERE clip_path IS NOT NULL;
-- The clips' total size, kept by triggers as snapshot_usage is.
CREATE TABLE IF NOT EXISTS clip_usage (
    id INTEGER PRIMARY KEY CHECK (id = 1),
    bytes INTEGER NOT NULL
);
INSERT OR IGNORE INTO clip_usage (id, bytes) SELECT 1, COALESCE(SUM(clip_bytes), 0) FROM events;
CREATE TRIGGER IF NOT EXISTS clip_usage_insert AFTER INSERT ON events BEGIN
    UPDATE clip_usage SET bytes = bytes + NEW.clip_bytes WHERE id = 1;
END;
CREATE TRIGGER IF NOT EXISTS clip_usage_update AFTER UPDATE OF clip_bytes ON events BEGIN
    UPDATE clip_usage SET bytes = bytes + NEW.clip_bytes - OLD.clip_bytes WHERE id = 1;
END;
CREATE TRIGGER IF NOT EXISTS clip_usage_delete AFTER DELETE ON events BEGIN
    UPDATE clip_usage SET bytes = bytes - OLD.clip_bytes WHERE id = 1;
END;
-- A camera's motion while activated: the largest moving share (0..1) of each second.
CREATE TABLE IF NOT EXISTS activity (
    camera_id INTEGER NOT NULL,
    ts INTEGER NOT NULL,
    motion REAL NOT NULL,
    PRIMARY KEY (camera_id, ts)
) WITHOUT ROWID;
"""


class Database:
    def __init__(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self._lock = threading.RLock()
        self._conn = sqlite3.connect(str(path), check_same_thread=False, isolation_level=None)
        self._conn.row_factory = sqlite3.Row
        self._conn.execute("PRAGMA journal_mode=WAL")
        self._conn.execute("PRAGMA synchronous=FULL")
        self._conn.execute("PRAGMA busy_timeout=5000")
        # One transaction: the usage total is seeded and its triggers made together.
        self._conn.executescript(f"BEGIN IMMEDIATE;\n{SCHEMA}COMMIT;")
        self._add_missing_columns()
        self._add_recordings()

    def _add_missing_columns(self) -> None:
        present = {row["name"] for row in self._conn.execute("PRAGMA table_info(cameras)")}
        for column, definition in ADDED_CAMERA_COLUMNS.items():
            if column not in present:
                self._conn.execute(f"ALTER TABLE cameras ADD COLUMN {column} {definition}")

    def _add_recordings(self) -> None:
        """The events' clip columns, their usage total and the activity table, in one
        transaction: the server and its camera processes may open an older database at once."""
        with self._tx() as conn:
            present = {row["name"] for row in conn.execute("PRAGMA table_info(events)")}
            for column, definition in ADDED_EVENT_COLUMNS.items():
                if column not in present:
                    conn.execute(f"ALTER TABLE events ADD COLUMN {column} {definition}")
            for statement in _statements(RECORDINGS_SCHEMA):
                conn.execute(statement)

    def close(self) -> None:
        with self._lock:
            self._conn.close()

    @property
    def journal_mode(self) -> str:
        row = self._query_one("PRAGMA journal_mode")
        return str(row[0]) if row else ""

    @contextmanager
    def _tx(self) -> Iterator[sqlite3.Connection]:
        with self._lock:
            self._conn.execute("BEGIN IMMEDIATE")
            try:
                yield self._conn
            except BaseException:
                self._conn.execute("ROLLBACK")
                raise
            self._conn.execute("COMMIT")

    def _query(self, sql: str, params: Sequence[Any] = ()) -> list[sqlite3.Row]:
        with self._lock:
            return list(self._conn.execute(sql, params))

    def _query_one(self, sql: str, params: Sequence[Any] = ()) -> sqlite3.Row | None:
        rows = self._query(sql, params)
        return rows[0] if rows else None

    # Cameras -------------------------------------------------------------------------------

    def add_camera(
        self, name: str, source: str, method: str, min_area: float, sensitivity: float | None = None
    ) -> int:
        with self._tx() as conn:
            cur = conn.execute(
                "INSERT INTO cameras (name, source, sensitivity, min_area, method, created_at)"
                " VALUES (?, ?, ?, ?, ?, ?)",
                (name, source, sensitivity, min_area, method, time.time()),
            )
            return int(cur.lastrowid or 0)

    def cameras(self) -> list[dict[str, Any]]:
        return [_camera(r) for r in self._query("SELECT * FROM cameras ORDER BY id")]

    def camera(self, camera_id: int) -> dict[str, Any] | None:
        if not _is_row_id(camera_id):
            return None
        row = self._query_one("SELECT * FROM cameras WHERE id = ?", (camera_id,))
        return _camera(row) if row else None

    def update_camera(self, camera_id: int, **fields: Any) -> dict[str, Any] | None:
        unknown = set(fields) - set(CAMERA_FIELDS)
        if unknown:
            raise ValueError(f"unknown camera fields: {sorted(unknown)}")
        if "mask" in fields:
            fields["mask"] = json.dumps(fields["mask"] or [])
        if fields:
            assignments = ", ".join(f"{k} = ?" for k in fields)
            with self._tx() as conn:
                conn.execute(
                    f"UPDATE cameras SET {assignments} WHERE id = ?",  # noqa: S608
                    (*fields.values(), camera_id),
                )
        return self.camera(camera_id)

    def delete_camera(self, camera_id: int) -> bool:
        with self._tx() as conn:
            return conn.execute("DELETE FROM cameras WHERE id = ?", (camera_id,)).rowcount > 0

    # Events --------------------------------------------------------------------------------

    def add_event(
        self,
        camera_id: int,
        started_at: float,
        boxes: list[list[int]],
        max_area: float,
        track_ids: Sequence[int] = (),
    ) -> int:
        with self._tx() as conn:
            cur = conn.execute(
                "INSERT INTO events (camera_id, started_at, boxes, max_area, track_ids)"
                " VALUES (?, ?, ?, ?, ?)",
                (camera_id, started_at, json.dumps(boxes), max_area, json.dumps(list(track_ids))),
            )
            return int(cur.lastrowid or 0)

    def end_event(
        self, event_id: int, ended_at: float, max_area: float, track_ids: Sequence[int] = ()
    ) -> None:
        with self._tx() as conn:
            conn.execute(
                "UPDATE events SET ended_at = ?, max_area = MAX(max_area, ?),"
                " track_ids = ? WHERE id = ?",
                (ended_at, max_area, json.dumps(sorted(track_ids)), event_id),
            )

    def close_open_events(self, camera_id: int | None = None) -> list[dict[str, Any]]:
        """End the events a killed run (or camera process) left open; the events it ended.

        Each ends at its last snapshot, or where it started: the last moment known
        to have had motion, not the moment the server came back.
        """
        with self._tx() as conn:
            rows = conn.execute(
                "UPDATE events SET ended_at = COALESCE("
                " (SELECT MAX(ts) FROM snapshots WHERE event_id = events.id), started_at)"
                " WHERE ended_at IS NULL AND (? IS NULL OR camera_id = ?) RETURNING *",
                (camera_id, camera_id),
            ).fetchall()
        return [_event(row) for row in rows]

    def events(
        self,
        camera_id: int | None = None,
        since: float | None = None,
        until: float | None = None,
        limit: int = 200,
    ) -> list[dict[str, Any]]:
        """Events newest first (by start). ``since`` and ``until`` select the events going
        on at some time between them, ends included: one that started before ``since``
        is in if it ended at ``since`` or later, or is still open (``ended_at`` null)."""
        if since is not None and until is not None and since > until:
            return []  # An empty window, as the snapshots' filter has it.
        clauses, params = _filters(
            camera_id, since, until, "(ended_at IS NULL OR ended_at >= ?)", "started_at <= ?"
        )
        rows = self._query(
            f"SELECT * FROM events{_where(clauses)}"  # noqa: S608
            " ORDER BY started_at DESC, id DESC LIMIT ?",
            (*params, limit),
        )
        return [_event(r) for r in rows]

    # Snapshots -----------------------------------------------------------------------------

    def add_snapshot(
        self, camera_id: int, event_id: int | None, ts: float, kind: str, path: str, size: int
    ) -> int:
        with self._tx() as conn:
            cur = conn.execute(
                "INSERT INTO snapshots (camera_id, event_id, ts, kind, path, size)"
                " VALUES (?, ?, ?, ?, ?, ?)",
                (camera_id, event_id, ts, kind, path, size),
            )
            return int(cur.lastrowid or 0)

    def snapshots(
        self,
        camera_id: int | None = None,
        since: float | None = None,
        until: float | None = None,
        kind: str | None = None,
        ids: Sequence[int] | None = None,
        limit: int = 500,
        *,
        since_id: int | None = None,
        until_id: int | None = None,
    ) -> list[dict[str, Any]]:
        """Newest first (by time, then id). ``since_id`` and ``until_id`` settle ties at the
        window's ends, where snapshots share a time: of those taken at exactly ``since``,
        only ids from ``since_id`` on; at exactly ``until``, only ids up to ``until_id``.
        So a snapshot's (ts, id) as either end is a cursor that skips none and repeats none.
        Each counts only with its end given."""
        clauses, params = _filters(camera_id, since, until, "ts >= ?", "ts <= ?")
        if since is not None and since_id is not None:
            clauses.append("(ts > ? OR id >= ?)")
            params.extend((since, since_id))
        if until is not None and until_id is not None:
            clauses.append("(ts < ? OR id <= ?)")
            params.extend((until, until_id))
        if kind:
            clauses.append("kind = ?")
            params.append(kind)
        if ids is not None:
            clauses.append(f"id IN ({', '.join('?' for _ in ids) or 'NULL'})")
            params.extend(ids)
        sql = f"SELECT * FROM snapshots{_where(clauses)} ORDER BY ts DESC, id DESC LIMIT ?"  # noqa: S608
        return [dict(r) for r in self._query(sql, (*params, limit))]

    def snapshot(self, snapshot_id: int) -> dict[str, Any] | None:
        if not _is_row_id(snapshot_id):
            return None
        row = self._query_one("SELECT * FROM snapshots WHERE id = ?", (snapshot_id,))
        return dict(row) if row else None

    def delete_snapshots(self, ids: Sequence[int]) -> list[dict[str, Any]]:
        """Remove the rows; returns them so the caller can remove the files."""
        ids = [i for i in ids if _is_row_id(i)]
        if not ids:
            return []
        rows = self.snapshots(ids=ids, limit=len(ids))
        with self._tx() as conn:
            conn.executemany("DELETE FROM snapshots WHERE id = ?", [(r["id"],) for r in rows])
        return rows

    def first_snapshots(self, event_ids: Sequence[int]) -> dict[int, int]:
        """The first ``frame`` snapshot of each of these events that has one, by event id."""
        found: dict[int, int] = {}
        ids = list(event_ids)
        for start in range(0, len(ids), 500):
            chunk = ids[start : start + 500]
            marks = ", ".join("?" for _ in chunk)
            for event_id, snapshot_id in self._query(
                "SELECT event_id, MIN(id) FROM snapshots WHERE kind = 'frame'"  # noqa: S608
                f" AND event_id IN ({marks}) GROUP BY event_id",
                chunk,
            ):
                found[event_id] = snapshot_id
        return found

    def snapshot_ids_of(self, event_ids: Sequence[int]) -> list[int]:
        """The ids of every snapshot of these events."""
        ids: list[int] = []
        events = [i for i in event_ids if _is_row_id(i)]
        for start in range(0, len(events), 500):
            chunk = events[start : start + 500]
            marks = ", ".join("?" for _ in chunk)
            rows = self._query(
                f"SELECT id FROM snapshots WHERE event_id IN ({marks})",  # noqa: S608
                chunk,
            )
            ids.extend(row[0] for row in rows)
        return ids

    def open_events(self) -> int:
        """How many events have not ended (a camera is moving, or a run left them open)."""
        row = self._query_one("SELECT COUNT(*) FROM events WHERE ended_at IS NULL")
        return int(row[0]) if row else 0

    def snapshot_bytes(self) -> int:
        """The total size of every snapshot, from the running total (no scan)."""
        row = self._query_one("SELECT bytes FROM snapshot_usage WHERE id = 1")
        return int(row[0]) if row else 0

    def oldest_snapshots(self, limit: int) -> list[dict[str, Any]]:
        rows = self._query("SELECT * FROM snapshots ORDER BY ts, id LIMIT ?", (limit,))
        return [dict(r) for r in rows]

    def delete_events_without_snapshots(self, event_ids: Sequence[int]) -> int:
        """Delete those of ``event_ids`` that have ended and have no snapshot and no clip left."""
        with self._tx() as conn:
            return conn.executemany(
                "DELETE FROM events WHERE id = ? AND ended_at IS NOT NULL AND clip_path IS NULL"
                " AND NOT EXISTS (SELECT 1 FROM snapshots WHERE event_id = events.id)",
                [(event_id,) for event_id in event_ids],
            ).rowcount

    def delete_events_before(self, before: float) -> list[str]:
        """Delete the ended events that started before ``before`` (and the activity history
        as old); the paths of their clips, for the caller to delete the files."""
        with self._tx() as conn:
            rows = conn.execute(
                "DELETE FROM events WHERE started_at < ? AND ended_at IS NOT NULL"
                " AND (clip_path IS NULL OR clip_s IS NOT NULL) RETURNING clip_path",
                (before,),
            ).fetchall()
            cameras = conn.execute(
                "WITH RECURSIVE c(id) AS (SELECT MIN(camera_id) FROM activity UNION ALL"
                " SELECT (SELECT MIN(camera_id) FROM activity WHERE camera_id > c.id) FROM c"
                " WHERE c.id IS NOT NULL) SELECT id FROM c WHERE id IS NOT NULL"
            ).fetchall()
            conn.executemany(  # Per camera: along the primary key, not a scan.
                "DELETE FROM activity WHERE camera_id = ? AND ts < ?",
                [(row[0], before) for row in cameras],
            )
        return [row[0] for row in rows if row[0]]

    def delete_events(self, event_ids: Sequence[int]) -> list[dict[str, Any]]:
        """Delete those of ``event_ids`` that have ended and whose clip is not being
        recorded; their rows (the caller deletes their snapshots first, their clips after)."""
        ids = [i for i in event_ids if _is_row_id(i)]
        if not ids:
            return []
        marks = ", ".join("?" for _ in ids)
        with self._tx() as conn:
            rows = conn.execute(
                f"DELETE FROM events WHERE id IN ({marks}) AND ended_at IS NOT NULL"  # noqa: S608
                " AND (clip_path IS NULL OR clip_s IS NOT NULL) RETURNING *",
                ids,
            ).fetchall()
        return [_event(row) for row in rows]

    def event(self, event_id: int) -> dict[str, Any] | None:
        if not _is_row_id(event_id):
            return None
        row = self._query_one("SELECT * FROM events WHERE id = ?", (event_id,))
        return _event(row) if row else None

    # Clips ---------------------------------------------------------------------------------

    def start_clip(self, event_id: int, path: str, started_at: float) -> None:
        """The event's clip is being recorded into ``path`` (``clip_s`` null until done)."""
        with self._tx() as conn:
            conn.execute(
                "UPDATE events SET clip_path = ?, clip_started_at = ?, clip_s = NULL,"
                " clip_bytes = 0, clip_error = NULL WHERE id = ?",
                (path, started_at, event_id),
            )

    def finish_clip(
        self, event_id: int, size: int, clip_s: float, error: str | None = None
    ) -> bool:
        """The clip is written: its size and length (``error``: why it was cut short). False
        when the event is gone (deleted meanwhile): the caller deletes the file."""
        with self._tx() as conn:
            return (
                conn.execute(
                    "UPDATE events SET clip_bytes = ?, clip_s = ?, clip_error = ?"
                    " WHERE id = ? AND clip_path IS NOT NULL",
                    (size, clip_s, error, event_id),
                ).rowcount
                > 0
            )

    def drop_clip(self, event_id: int, error: str) -> None:
        """The event has no clip (any more), and ``error`` says why."""
        with self._tx() as conn:
            conn.execute(
                "UPDATE events SET clip_path = NULL, clip_bytes = 0, clip_s = NULL,"
                " clip_error = ? WHERE id = ?",
                (error, event_id),
            )

    def unfinished_clips(self, camera_id: int | None = None) -> list[dict[str, Any]]:
        """Events whose clip was being recorded when its camera's process ended."""
        rows = self._query(
            "SELECT * FROM events WHERE clip_path IS NOT NULL AND clip_s IS NULL"
            " AND (? IS NULL OR camera_id = ?) ORDER BY id",
            (camera_id, camera_id),
        )
        return [_event(r) for r in rows]

    def clip_bytes(self) -> int:
        """The total size of every clip, from the running total (no scan)."""
        row = self._query_one("SELECT bytes FROM clip_usage WHERE id = 1")
        return int(row[0]) if row else 0

    def oldest_clips(self, limit: int) -> list[dict[str, Any]]:
        """Finished clips, oldest event first."""
        rows = self._query(
            "SELECT * FROM events WHERE clip_path IS NOT NULL AND clip_s IS NOT NULL"
            " ORDER BY started_at, id LIMIT ?",
            (limit,),
        )
        return [_event(r) for r in rows]

    # Activity ------------------------------------------------------------------------------

    def add_activity(self, camera_id: int, seconds: Sequence[tuple[int, float]]) -> None:
        """Rows of (second, largest moving share in it); a second written twice keeps the
        larger share."""
        with self._tx() as conn:
            conn.executemany(
                "INSERT INTO activity (camera_id, ts, motion) VALUES (?, ?, ?)"
                " ON CONFLICT (camera_id, ts) DO UPDATE SET motion = MAX(motion, excluded.motion)",
                [(camera_id, ts, motion) for ts, motion in seconds],
            )

    def activity(
        self, camera_id: int, since: float, until: float, step: float
    ) -> dict[int, tuple[float | None, int]]:
        """Per step from ``since`` (``(ts - since) // step``, up to ``until``, excluded): the
        largest moving share written in it (None: none, the camera was not activated) and
        the number of the camera's events that started in it. Steps with neither are left
        out."""
        steps: dict[int, tuple[float | None, int]] = {}
        for index, motion in self._query(
            "SELECT CAST((ts - ?) / ? AS INTEGER) AS step, MAX(motion) FROM activity"
            " WHERE camera_id = ? AND ts >= ? AND ts < ? GROUP BY step",
            (since, step, camera_id, math.ceil(since), until),
        ):
            steps[index] = (motion, 0)
        for index, count in self._query(
            "SELECT CAST((started_at - ?) / ? AS INTEGER) AS step, COUNT(*) FROM events"
            " WHERE camera_id = ? AND started_at >= ? AND started_at < ? GROUP BY step",
            (since, step, camera_id, since, until),
        ):
            steps[index] = (steps.get(index, (None, 0))[0], count)
        return steps

    # Analyses ------------------------------------------------------------------------------

    def add_analysis(self, analysis_id: str, filename: str, options: dict[str, Any]) -> None:
        with self._tx() as conn:
            conn.execute(
                "INSERT INTO analyses (id, filename, status, options, created_at)"
                " VALUES (?, ?, 'queued', ?, ?)",
                (analysis_id, filename, json.dumps(options), time.time()),
            )

    def update_analysis(self, analysis_id: str, **fields: Any) -> None:
        allowed = {"status", "progress", "error", "finished_at"}
        if set(fields) - allowed:
            raise ValueError(f"unknown analysis fields: {sorted(set(fields) - allowed)}")
        assignments = ", ".join(f"{k} = ?" for k in fields)
        with self._tx() as conn:
            conn.execute(
                f"UPDATE analyses SET {assignments} WHERE id = ?",  # noqa: S608
                (*fields.values(), analysis_id),
            )

    def analysis(self, analysis_id: str) -> dict[str, Any] | None:
        row = self._query_one("SELECT * FROM analyses WHERE id = ?", (analysis_id,))
        return _analysis(row) if row else None

    def analyses(self, limit: int = 100) -> list[dict[str, Any]]:
        rows = self._query("SELECT * FROM analyses ORDER BY created_at DESC LIMIT ?", (limit,))
        return [_analysis(r) for r in rows]

    def fail_unfinished_analyses(self, reason: str) -> int:
        with self._tx() as conn:
            return conn.execute(
                "UPDATE analyses SET status = 'failed', error = ?, finished_at = ?"
                " WHERE status IN ('queued', 'running')",
                (reason, time.time()),
            ).rowcount

    # Notification targets ------------------------------------------------------------------

    def add_target(self, url: str, cameras: Sequence[int] | None, origin: str = "api") -> int:
        """A new target; sqlite3.IntegrityError if one has this URL already."""
        with self._tx() as conn:
            cur = conn.execute(
                "INSERT INTO notification_targets (url, cameras, origin, created_at)"
                " VALUES (?, ?, ?, ?)",
                (url, _json_or_null(cameras), origin, time.time()),
            )
            return int(cur.lastrowid or 0)

    def targets(self) -> list[dict[str, Any]]:
        rows = self._query("SELECT * FROM notification_targets ORDER BY id")
        return [_target(r) for r in rows]

    def target(self, target_id: int) -> dict[str, Any] | None:
        if not _is_row_id(target_id):
            return None
        row = self._query_one("SELECT * FROM notification_targets WHERE id = ?", (target_id,))
        return _target(row) if row else None

    def delete_target(self, target_id: int) -> bool:
        if not _is_row_id(target_id):
            return False
        with self._tx() as conn:
            deleted = conn.execute("DELETE FROM notification_targets WHERE id = ?", (target_id,))
            return deleted.rowcount > 0

    def sync_env_targets(self, urls: Sequence[str]) -> tuple[int, int]:
        """Make the targets of origin ``env`` those of ``urls`` (VIGIL_NOTIFY_URLS): the
        ones no longer listed are deleted, the new ones added (a URL already a target, of
        any origin, stays as it is). How many were added and deleted."""
        wanted = list(dict.fromkeys(urls))
        with self._tx() as conn:
            listed = [
                (row["id"], row["url"], row["origin"])
                for row in conn.execute("SELECT id, url, origin FROM notification_targets")
            ]
            gone = [(i,) for i, url, origin in listed if origin == "env" and url not in wanted]
            conn.executemany("DELETE FROM notification_targets WHERE id = ?", gone)
            known = {url for _, url, _ in listed}
            new = [url for url in wanted if url not in known]
            now = time.time()
            conn.executemany(
                "INSERT INTO notification_targets (url, cameras, origin, created_at)"
                " VALUES (?, NULL, 'env', ?)",
                [(url, now) for url in new],
            )
        return len(new), len(gone)


def _statements(script: str) -> list[str]:
    """The statements of ``script`` (one per ``;`` at a line's end, triggers whole)."""
    statements: list[str] = []
    current: list[str] = []
    for line in script.strip().splitlines():
        if line.startswith("--") and not current:
            continue
        current.append(line)
        text = "\n".join(current)
        if line.rstrip().endswith(";") and sqlite3.complete_statement(text):
            statements.append(text)
            current = []
    return statements


def _filters(
    camera_id: int | None,
    since: float | None,
    until: float | None,
    since_clause: str,
    until_clause: str,
) -> tuple[list[str], list[Any]]:
    """A listing's filters as SQL clauses (to be joined with AND) and their parameters:
    the camera, and the window, whose ends the clauses test (each with one ``?``): that
    a row ends no earlier than ``since`` and starts no later than ``until``."""
    clauses: list[str] = []
    params: list[Any] = []
    given = (("camera_id = ?", camera_id), (since_clause, since), (until_clause, until))
    for clause, value in given:
        if value is not None:
            clauses.append(clause)
            params.append(value)
    return clauses, params


def _where(clauses: Sequence[str]) -> str:
    return " WHERE " + " AND ".join(clauses) if clauses else ""


def _camera(row: sqlite3.Row) -> dict[str, Any]:
    out = dict(row)
    out["show_mask"] = bool(out["show_mask"])
    out["mask"] = json.loads(out["mask"])
    out["active"] = bool(out["active"])
    return out


def _event(row: sqlite3.Row) -> dict[str, Any]:
    out = dict(row)
    out["boxes"] = json.loads(out["boxes"])
    out["track_ids"] = json.loads(out["track_ids"])
    return out


def _analysis(row: sqlite3.Row) -> dict[str, Any]:
    out = dict(row)
    out["options"] = json.loads(out["options"])
    return out


def _target(row: sqlite3.Row) -> dict[str, Any]:
    out = dict(row)
    out["cameras"] = None if out["cameras"] is None else json.loads(out["cameras"])
    return out


def _json_or_null(value: Sequence[int] | None) -> str | None:
    return None if value is None else json.dumps(list(value))


def _is_row_id(value: int) -> bool:
    """Whether SQLite can hold ``value`` (a 64-bit integer): beyond it no row has it, and
    binding it raises OverflowError."""
    return -(2**63) <= value < 2**63
