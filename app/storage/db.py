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

    def _add_missing_columns(self) -> None:
        present = {row["name"] for row in self._conn.execute("PRAGMA table_info(cameras)")}
        for column, definition in ADDED_CAMERA_COLUMNS.items():
            if column not in present:
                self._conn.execute(f"ALTER TABLE cameras ADD COLUMN {column} {definition}")

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
        """Delete those of ``event_ids`` that have ended and have no snapshot left."""
        with self._tx() as conn:
            return conn.executemany(
                "DELETE FROM events WHERE id = ? AND ended_at IS NOT NULL"
                " AND NOT EXISTS (SELECT 1 FROM snapshots WHERE event_id = events.id)",
                [(event_id,) for event_id in event_ids],
            ).rowcount

    def delete_events_before(self, before: float) -> int:
        with self._tx() as conn:
            return conn.execute(
                "DELETE FROM events WHERE started_at < ? AND ended_at IS NOT NULL", (before,)
            ).rowcount

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
