"""The database: cameras, events with their clips, snapshots, analyses, notification targets
and the activity history, in SQLite (the data folder's ``vigil.db``) or in PostgreSQL
(``VIGIL_DATABASE_URL``). Each query is built once, with SQLAlchemy Core, from the tables of
``app.storage.schema``; ``app.storage.engine`` says how each process connects, and
``app.storage.migrate`` how the schema is made and kept up to date.

Every write is one short transaction; an alarm's rows are committed before its message goes
out. Rows come back as plain dicts, JSON columns decoded.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from sqlalchemy import (
    BigInteger,
    ColumnElement,
    Connection,
    Double,
    FunctionElement,
    Insert,
    Select,
    Table,
    case,
    delete,
    func,
    insert,
    literal,
    select,
    update,
)
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.exc import IntegrityError
from sqlalchemy.ext.compiler import compiles
from sqlalchemy.sql.compiler import SQLCompiler

from app.storage import engine as engines
from app.storage import migrate as migrations
from app.storage.schema import (
    activity,
    analyses,
    cameras,
    clip_usage,
    events,
    file_deletions,
    notification_targets,
    snapshot_usage,
    snapshots,
)

__all__ = ["Database", "DatabaseClosedError", "IntegrityError"]

CAMERA_FIELDS = (
    "name",
    "source",
    "sensitivity",
    "min_area",
    "method",
    "show_mask",
    "active",
    "mask",
    "pinned_to",
)
FLAGS = ("show_mask", "active")
"""Camera fields kept as 0 or 1."""
ANALYSIS_FIELDS = frozenset({"status", "progress", "error", "finished_at"})
CHUNK = 500
FIRST_CAMERA_LOCK = 0x76696763  # "vigc": PostgreSQL's advisory lock of add_first_camera.
"""Ids per ``IN (...)`` of a long list."""


class Database:
    """The database at ``target``: a SQLite file's path, or a PostgreSQL URL.

    ``migrate``: bring its schema up to this release's first (the server does, at start);
    otherwise wait until it is (a camera process: the server migrates before starting one).
    ``app.storage.migrate.SchemaError`` when it cannot be. ``node``: the node this process
    belongs to (``VIGIL_NODE_NAME``), named by the events and snapshots it adds.
    """

    def __init__(
        self, target: engines.Target, *, migrate: bool = True, node: str | None = None
    ) -> None:
        self.node = node
        self.dialect = engines.engine_name(target)
        """``sqlite`` or ``postgresql``."""
        self.shown = engines.shown(target)
        """Where it is, for logs: a path, or the URL without its password."""
        self.path = target if isinstance(target, Path) else None
        if migrate:
            migrations.upgrade(target)
        self.engine = engines.create(target)
        """SQLAlchemy's engine (its pool: this process's connections)."""
        self._write = engines.writer(self.engine)
        self._read = engines.reader(self.engine)
        self._closed = False
        if not migrate:
            try:
                migrations.wait_for_head(self.engine)
            except BaseException:
                self.engine.dispose()
                raise

    def close(self) -> None:
        """Close its connections; any use after is a ``DatabaseClosedError``."""
        self._closed = True
        self.engine.dispose()

    def _check_open(self) -> None:
        if self._closed:
            raise DatabaseClosedError("the database is closed")

    def _reading(self) -> Connection:
        """A connection for reads (``with`` it: given back to the pool at the end)."""
        self._check_open()
        return self._read.connect()

    @property
    def journal_mode(self) -> str:
        """SQLite's journal mode (``wal``); empty on PostgreSQL."""
        if self.dialect != engines.SQLITE:
            return ""
        with self._reading() as conn:
            return str(conn.exec_driver_sql("PRAGMA journal_mode").scalar())

    @property
    def revision(self) -> str | None:
        """The schema's revision (``app/storage/migrations/versions``)."""
        with self._reading() as conn:
            return migrations.revision(conn)

    @contextmanager
    def transaction(self) -> Iterator[Connection]:
        """A writing transaction, committed at the end of the block (rolled back on an
        exception). On SQLite it holds the database's write lock throughout; on PostgreSQL,
        ``select(...).with_for_update(skip_locked=True)`` locks rows until it ends.

        Use only the connection it gives within it: on SQLite it is the process's only one.
        """
        self._check_open()
        with self._write.begin() as conn:
            yield conn

    def _rows(self, query: Select[Any]) -> list[dict[str, Any]]:
        with self._reading() as conn:
            return [dict(row) for row in conn.execute(query).mappings()]

    def _row(self, query: Select[Any]) -> dict[str, Any] | None:
        rows = self._rows(query)
        return rows[0] if rows else None

    def _scalar(self, query: Select[Any]) -> Any:
        with self._reading() as conn:
            return conn.execute(query).scalar()

    def _insert(self, statement: Insert) -> int:
        with self.transaction() as conn:
            return _inserted_id(conn, statement)

    # Cameras -------------------------------------------------------------------------------

    def add_camera(
        self, name: str, source: str, method: str, min_area: float, sensitivity: float | None = None
    ) -> int:
        return self._insert(_new_camera(name, source, method, min_area, sensitivity))

    def add_first_camera(self, name: str, source: str, method: str, min_area: float) -> int | None:
        """Add this camera if there is none at all (a fresh install's demo camera): its id,
        or None. Of nodes starting together, one adds it: on PostgreSQL the look and the
        insert hold a lock of their own for the transaction, as SQLite's write lock does."""
        with self.transaction() as conn:
            if conn.dialect.name == engines.POSTGRESQL:
                conn.execute(select(func.pg_advisory_xact_lock(FIRST_CAMERA_LOCK)))
            if conn.execute(select(cameras.c.id).limit(1)).first() is not None:
                return None
            key = conn.execute(_new_camera(name, source, method, min_area)).inserted_primary_key
        assert key is not None
        return int(key[0])

    def cameras(self) -> list[dict[str, Any]]:
        return [_camera(r) for r in self._rows(select(cameras).order_by(cameras.c.id))]

    def camera(self, camera_id: int) -> dict[str, Any] | None:
        if not _is_row_id(camera_id):
            return None
        row = self._row(select(cameras).where(cameras.c.id == camera_id))
        return _camera(row) if row else None

    def update_camera(self, camera_id: int, **fields: Any) -> dict[str, Any] | None:
        unknown = set(fields) - set(CAMERA_FIELDS)
        if unknown:
            raise ValueError(f"unknown camera fields: {sorted(unknown)}")
        if "mask" in fields:
            fields["mask"] = json.dumps(fields["mask"] or [])
        for flag in FLAGS:
            if flag in fields:
                fields[flag] = int(bool(fields[flag]))
        if not _is_row_id(camera_id):
            return None
        if fields:
            with self.transaction() as conn:
                conn.execute(update(cameras).where(cameras.c.id == camera_id).values(**fields))
        return self.camera(camera_id)

    def delete_camera(self, camera_id: int) -> bool:
        if not _is_row_id(camera_id):
            return False
        with self.transaction() as conn:
            return conn.execute(delete(cameras).where(cameras.c.id == camera_id)).rowcount > 0

    # Events --------------------------------------------------------------------------------

    def add_event(
        self,
        camera_id: int,
        started_at: float,
        boxes: list[list[int]],
        max_area: float,
        track_ids: Sequence[int] = (),
    ) -> int:
        return self._insert(
            insert(events).values(
                camera_id=camera_id,
                started_at=started_at,
                boxes=json.dumps(boxes),
                max_area=max_area,
                track_ids=json.dumps(list(track_ids)),
                node=self.node,
            )
        )

    def end_event(
        self, event_id: int, ended_at: float, max_area: float, track_ids: Sequence[int] = ()
    ) -> None:
        with self.transaction() as conn:
            conn.execute(
                update(events)
                .where(events.c.id == event_id)
                .values(
                    ended_at=ended_at,
                    max_area=_greater(events.c.max_area, literal(max_area, Double)),
                    track_ids=json.dumps(sorted(track_ids)),
                )
            )

    def close_open_events(self, camera_id: int | None = None) -> list[dict[str, Any]]:
        """End the events a killed run (or camera process) left open; the events it ended.

        Each ends at its last snapshot, or where it started: the last moment known
        to have had motion, not the moment the server came back.
        """
        last = select(func.max(snapshots.c.ts)).where(snapshots.c.event_id == events.c.id)
        statement = (
            update(events)
            .where(events.c.ended_at.is_(None))
            .values(ended_at=func.coalesce(last.scalar_subquery(), events.c.started_at))
            .returning(*events.c)
        )
        if camera_id is not None:
            statement = statement.where(events.c.camera_id == camera_id)
        with self.transaction() as conn:
            rows = conn.execute(statement).mappings().all()
        return [_event(dict(row)) for row in rows]

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
        query = select(events)
        if camera_id is not None:
            query = query.where(events.c.camera_id == camera_id)
        if since is not None:
            query = query.where(events.c.ended_at.is_(None) | (events.c.ended_at >= since))
        if until is not None:
            query = query.where(events.c.started_at <= until)
        query = query.order_by(events.c.started_at.desc(), events.c.id.desc()).limit(_limit(limit))
        return [_event(r) for r in self._rows(query)]

    # Snapshots -----------------------------------------------------------------------------

    def add_snapshot(
        self, camera_id: int, event_id: int | None, ts: float, kind: str, path: str, size: int
    ) -> int:
        return self.add_snapshots(camera_id, event_id, ts, [(kind, path, size)])[0]

    def add_snapshots(
        self,
        camera_id: int,
        event_id: int | None,
        ts: float,
        pictures: Sequence[tuple[str, str, int]],
    ) -> list[int]:
        """Rows of pictures taken together, each (kind, path, size), in one transaction (one
        commit: an alarm's frame and difference picture); their ids, in that order."""
        ids = []
        with self.transaction() as conn:
            for kind, path, size in pictures:
                statement = insert(snapshots).values(
                    camera_id=camera_id,
                    event_id=event_id,
                    ts=ts,
                    kind=kind,
                    path=path,
                    size=size,
                    node=self.node,
                )
                ids.append(_inserted_id(conn, statement))
        return ids

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
        s = snapshots.c
        query = select(snapshots)
        if camera_id is not None:
            query = query.where(s.camera_id == camera_id)
        if since is not None:
            query = query.where(s.ts >= since)
            if since_id is not None:
                query = query.where((s.ts > since) | (s.id >= since_id))
        if until is not None:
            query = query.where(s.ts <= until)
            if until_id is not None:
                query = query.where((s.ts < until) | (s.id <= until_id))
        if kind:
            query = query.where(s.kind == kind)
        query = query.order_by(s.ts.desc(), s.id.desc()).limit(_limit(limit))
        if ids is None:
            return self._rows(query)
        # A long list a piece at a time (a statement takes so many values), then merged.
        rows = [row for chunk in _chunks(ids) for row in self._rows(query.where(s.id.in_(chunk)))]
        return sorted(rows, key=lambda r: (r["ts"], r["id"]), reverse=True)[: max(limit, 0)]

    def snapshot(self, snapshot_id: int) -> dict[str, Any] | None:
        if not _is_row_id(snapshot_id):
            return None
        return self._row(select(snapshots).where(snapshots.c.id == snapshot_id))

    def delete_snapshots(self, ids: Sequence[int]) -> list[dict[str, Any]]:
        """Remove the rows; returns them (newest first) so the caller can remove the files.
        Only the rows this call deleted: of two deleting one snapshot at once, one has it."""
        deleted = self._delete_returning(snapshots, ids, files=("snapshot", "path"))
        return sorted(deleted, key=lambda r: (r["ts"], r["id"]), reverse=True)

    def first_snapshots(self, event_ids: Sequence[int]) -> dict[int, int]:
        """The first ``frame`` snapshot of each of these events that has one, by event id."""
        found: dict[int, int] = {}
        s = snapshots.c
        for chunk in _chunks(event_ids):
            query = (
                select(s.event_id, func.min(s.id))
                .where(s.kind == "frame", s.event_id.in_(chunk))
                .group_by(s.event_id)
            )
            with self._reading() as conn:
                found.update({int(e): int(i) for e, i in conn.execute(query)})
        return found

    def snapshot_ids_of(self, event_ids: Sequence[int]) -> list[int]:
        """The ids of every snapshot of these events."""
        ids: list[int] = []
        for chunk in _chunks(event_ids):
            query = select(snapshots.c.id).where(snapshots.c.event_id.in_(chunk))
            with self._reading() as conn:
                ids.extend(conn.execute(query).scalars())
        return ids

    def open_events(self) -> int:
        """How many events have not ended (a camera is moving, or a run left them open)."""
        query = select(func.count()).select_from(events).where(events.c.ended_at.is_(None))
        return int(self._scalar(query) or 0)

    def snapshot_bytes(self) -> int:
        """The total size of every snapshot, from the running total (no scan)."""
        return int(self._scalar(select(func.sum(snapshot_usage.c.bytes))) or 0)

    def oldest_snapshots(self, limit: int) -> list[dict[str, Any]]:
        query = select(snapshots).order_by(snapshots.c.ts, snapshots.c.id).limit(_limit(limit))
        return self._rows(query)

    def delete_events_without_snapshots(self, event_ids: Sequence[int]) -> int:
        """Delete those of ``event_ids`` that have ended and have no snapshot and no clip left."""
        e = events.c
        without = ~select(snapshots.c.id).where(snapshots.c.event_id == e.id).exists()
        deleted = 0
        with self.transaction() as conn:
            for chunk in _chunks(event_ids):
                statement = delete(events).where(
                    e.id.in_(chunk), e.ended_at.is_not(None), e.clip_path.is_(None), without
                )
                deleted += conn.execute(statement).rowcount
        return deleted

    def delete_events_before(self, before: float) -> list[str]:
        """Delete the ended events that started before ``before`` (and the activity history
        as old); the paths of their clips, for the caller to delete the files."""
        e = events.c
        statement = (
            delete(events)
            .where(e.started_at < before, e.ended_at.is_not(None), _clip_not_recording())
            .returning(e.clip_path, e.node)
        )
        with self.transaction() as conn:
            deleted = conn.execute(statement).all()
            self._hand_over(conn, "clip", deleted)
            paths = [path for path, _ in deleted]
            camera_ids = list(conn.execute(_activity_cameras()).scalars())
            for camera_id in camera_ids:  # Per camera: along the primary key, not a scan.
                conn.execute(
                    delete(activity).where(
                        activity.c.camera_id == camera_id, activity.c.ts < math.ceil(before)
                    )
                )
        return [path for path in paths if path]

    def delete_events(self, event_ids: Sequence[int]) -> list[dict[str, Any]]:
        """Delete those of ``event_ids`` that have ended and whose clip is not being
        recorded; their rows (the caller deletes their snapshots first, their clips after)."""
        rows = self._delete_returning(
            events,
            event_ids,
            events.c.ended_at.is_not(None),
            _clip_not_recording(),
            files=("clip", "clip_path"),
        )
        return [_event(row) for row in rows]

    def event(self, event_id: int) -> dict[str, Any] | None:
        if not _is_row_id(event_id):
            return None
        row = self._row(select(events).where(events.c.id == event_id))
        return _event(row) if row else None

    def _delete_returning(
        self,
        table: Table,
        ids: Sequence[int],
        *conditions: ColumnElement[bool],
        files: tuple[str, str] | None = None,
    ) -> list[dict[str, Any]]:
        """``files``: the kind of file the rows name and its column, for ``_hand_over``."""
        rows: list[dict[str, Any]] = []
        with self.transaction() as conn:
            for chunk in _chunks(ids):
                statement = (
                    delete(table).where(table.c.id.in_(chunk), *conditions).returning(*table.c)
                )
                found = [dict(row) for row in conn.execute(statement).mappings()]
                if files is not None:
                    kind, column = files
                    self._hand_over(conn, kind, [(r[column], r["node"]) for r in found])
                rows.extend(found)
        return rows

    def _hand_over(
        self, conn: Connection, kind: str, files: Sequence[tuple[str | None, str | None]]
    ) -> None:
        """Of the files of rows just deleted, ``(path, node)``, those another node of the site
        holds: for it to delete (``take_file_deletions``), in the same transaction as the
        rows, so none is forgotten. Alone (SQLite) every file is this node's."""
        if self.dialect != engines.POSTGRESQL or self.node is None:
            return
        theirs = [
            {"node": node, "kind": kind, "path": path}
            for path, node in files
            if path and node is not None and node != self.node
        ]
        if theirs:
            conn.execute(insert(file_deletions), theirs)

    def take_file_deletions(self) -> list[tuple[str, str]]:
        """The files of this node whose rows another node deleted, ``(kind, path)``, taken
        off the list: the caller deletes them."""
        if self.node is None:
            return []
        statement = (
            delete(file_deletions)
            .where(file_deletions.c.node == self.node)
            .returning(file_deletions.c.kind, file_deletions.c.path)
        )
        with self.transaction() as conn:
            return [(kind, path) for kind, path in conn.execute(statement)]

    # Clips ---------------------------------------------------------------------------------

    def start_clip(self, event_id: int, path: str, started_at: float) -> None:
        """The event's clip is being recorded into ``path`` (``clip_s`` null until done)."""
        self._update_event(
            event_id,
            clip_path=path,
            clip_started_at=started_at,
            clip_s=None,
            clip_bytes=0,
            clip_error=None,
        )

    def finish_clip(
        self, event_id: int, size: int, clip_s: float, error: str | None = None
    ) -> bool:
        """The clip is written: its size and length (``error``: why it was cut short). False
        when the event is gone (deleted meanwhile): the caller deletes the file."""
        statement = (
            update(events)
            .where(events.c.id == event_id, events.c.clip_path.is_not(None))
            .values(clip_bytes=size, clip_s=clip_s, clip_error=error)
        )
        with self.transaction() as conn:
            return conn.execute(statement).rowcount > 0

    def drop_clip(self, event_id: int, error: str) -> None:
        """The event has no clip (any more), and ``error`` says why."""
        e = events.c
        with self.transaction() as conn:
            clip = conn.execute(select(e.clip_path, e.node).where(e.id == event_id)).all()
            conn.execute(
                update(events)
                .where(e.id == event_id)
                .values(clip_path=None, clip_bytes=0, clip_s=None, clip_error=error)
            )
            self._hand_over(conn, "clip", clip)

    def _update_event(self, event_id: int, **values: Any) -> None:
        with self.transaction() as conn:
            conn.execute(update(events).where(events.c.id == event_id).values(**values))

    def unfinished_clips(self, camera_id: int | None = None) -> list[dict[str, Any]]:
        """Events whose clip was being recorded when its camera's process ended: of those
        whose file is on this node's disk (made by ``node``, or before nodes), when it has one.
        Another node's stay as they are until that node finishes them at its start."""
        query = select(events).where(events.c.clip_path.is_not(None), events.c.clip_s.is_(None))
        if self.node is not None:
            query = query.where(events.c.node.is_(None) | (events.c.node == self.node))
        if camera_id is not None:
            query = query.where(events.c.camera_id == camera_id)
        return [_event(r) for r in self._rows(query.order_by(events.c.id))]

    def clip_bytes(self) -> int:
        """The total size of every clip, from the running total (no scan)."""
        return int(self._scalar(select(func.sum(clip_usage.c.bytes))) or 0)

    def oldest_clips(self, limit: int) -> list[dict[str, Any]]:
        """Finished clips, oldest event first."""
        query = (
            select(events)
            .where(events.c.clip_path.is_not(None), events.c.clip_s.is_not(None))
            .order_by(events.c.started_at, events.c.id)
            .limit(_limit(limit))
        )
        return [_event(r) for r in self._rows(query)]

    # Activity ------------------------------------------------------------------------------

    def add_activity(self, camera_id: int, seconds: Sequence[tuple[int, float]]) -> None:
        """Rows of (second, largest moving share in it); a second written twice keeps the
        larger share."""
        largest: dict[int, float] = {}
        for ts, motion in seconds:  # One row per second: one statement cannot set one twice.
            largest[ts] = max(motion, largest.get(ts, motion))
        if not largest:
            return
        dialect = postgresql if self.dialect == engines.POSTGRESQL else sqlite
        statement = dialect.insert(activity)
        statement = statement.on_conflict_do_update(
            index_elements=[activity.c.camera_id, activity.c.ts],
            set_={"motion": _greater(activity.c.motion, statement.excluded.motion)},
        )
        rows = [{"camera_id": camera_id, "ts": ts, "motion": m} for ts, m in largest.items()]
        with self.transaction() as conn:
            conn.execute(statement, rows)

    def activity(
        self, camera_id: int, since: float, until: float, step: float
    ) -> dict[int, tuple[float | None, int]]:
        """Per step from ``since`` (``(ts - since) // step``, up to ``until``, excluded): the
        largest moving share written in it (None: none, the camera was not activated) and
        the number of the camera's events that started in it. Steps with neither are left
        out."""
        start, width = literal(float(since), Double), literal(float(step), Double)
        a = activity.c
        in_step = _Whole((a.ts - start) / width).label("step")
        motion = (
            select(in_step, func.max(a.motion))
            .where(a.camera_id == camera_id, a.ts >= math.ceil(since), a.ts < math.ceil(until))
            .group_by(in_step)
        )
        e = events.c
        started = _Whole((e.started_at - start) / width).label("step")
        counts = (
            select(started, func.count())
            .where(e.camera_id == camera_id, e.started_at >= since, e.started_at < until)
            .group_by(started)
        )
        steps: dict[int, tuple[float | None, int]] = {}
        with self._reading() as conn:
            for index, largest in conn.execute(motion):
                steps[int(index)] = (largest, 0)
            for index, count in conn.execute(counts):
                steps[int(index)] = (steps.get(int(index), (None, 0))[0], int(count))
        return steps

    # Analyses ------------------------------------------------------------------------------

    def add_analysis(self, analysis_id: str, filename: str, options: dict[str, Any]) -> None:
        with self.transaction() as conn:
            conn.execute(
                insert(analyses).values(
                    id=analysis_id,
                    filename=filename,
                    status="queued",
                    options=json.dumps(options),
                    created_at=time.time(),
                    node=self.node,
                )
            )

    def update_analysis(self, analysis_id: str, **fields: Any) -> None:
        if set(fields) - ANALYSIS_FIELDS:
            raise ValueError(f"unknown analysis fields: {sorted(set(fields) - ANALYSIS_FIELDS)}")
        if fields:
            with self.transaction() as conn:
                conn.execute(update(analyses).where(analyses.c.id == analysis_id).values(**fields))

    def analysis(self, analysis_id: str) -> dict[str, Any] | None:
        row = self._row(select(analyses).where(analyses.c.id == analysis_id))
        return _analysis(row) if row else None

    def analyses(self, limit: int = 100) -> list[dict[str, Any]]:
        query = select(analyses).order_by(analyses.c.created_at.desc()).limit(_limit(limit))
        return [_analysis(r) for r in self._rows(query)]

    def fail_unfinished_analyses(self, reason: str) -> int:
        """Those this node (or one before nodes) was running when it stopped: not another's."""
        a = analyses.c
        statement = (
            update(analyses)
            .where(a.status.in_(("queued", "running")))
            .values(status="failed", error=reason, finished_at=time.time())
        )
        if self.node is not None:
            statement = statement.where(a.node.is_(None) | (a.node == self.node))
        with self.transaction() as conn:
            return conn.execute(statement).rowcount

    # Notification targets ------------------------------------------------------------------

    def add_target(self, url: str, cameras: Sequence[int] | None, origin: str = "api") -> int:
        """A new target; ``IntegrityError`` if one has this URL already."""
        return self._insert(
            insert(notification_targets).values(
                url=url, cameras=_json_or_null(cameras), origin=origin, created_at=time.time()
            )
        )

    def targets(self) -> list[dict[str, Any]]:
        query = select(notification_targets).order_by(notification_targets.c.id)
        return [_target(r) for r in self._rows(query)]

    def target(self, target_id: int) -> dict[str, Any] | None:
        if not _is_row_id(target_id):
            return None
        row = self._row(select(notification_targets).where(notification_targets.c.id == target_id))
        return _target(row) if row else None

    def delete_target(self, target_id: int) -> bool:
        if not _is_row_id(target_id):
            return False
        statement = delete(notification_targets).where(notification_targets.c.id == target_id)
        with self.transaction() as conn:
            return conn.execute(statement).rowcount > 0

    def sync_env_targets(self, urls: Sequence[str]) -> tuple[int, int]:
        """Make the targets of origin ``env`` those of ``urls`` (VIGIL_NOTIFY_URLS): the
        ones no longer listed are deleted, the new ones added (a URL already a target, of
        any origin, stays as it is). How many were added and deleted."""
        wanted = list(dict.fromkeys(urls))
        t = notification_targets.c
        with self.transaction() as conn:
            listed = conn.execute(select(t.id, t.url, t.origin)).all()
            gone = [i for i, url, origin in listed if origin == "env" and url not in wanted]
            for chunk in _chunks(gone):
                conn.execute(delete(notification_targets).where(t.id.in_(chunk)))
            known = {url for _, url, _ in listed}
            new = [url for url in wanted if url not in known]
            now = time.time()
            for url in new:
                conn.execute(
                    insert(notification_targets).values(
                        url=url, cameras=None, origin="env", created_at=now
                    )
                )
        return len(new), len(gone)


class DatabaseClosedError(RuntimeError):
    """The Database was closed (its process is stopping)."""


class _Whole(FunctionElement[int]):
    """The whole part of a number that is not negative (a step's index)."""

    type = BigInteger()
    name = "whole"
    inherit_cache = True


@compiles(_Whole)
def _whole_sqlite(element: _Whole, compiler: SQLCompiler, **kw: Any) -> str:
    return f"CAST({compiler.process(element.clauses, **kw)} AS INTEGER)"  # Truncates.


@compiles(_Whole, "postgresql")
def _whole_postgres(element: _Whole, compiler: SQLCompiler, **kw: Any) -> str:
    # PostgreSQL's CAST would round; floor() first.
    return f"CAST(floor({compiler.process(element.clauses, **kw)}) AS BIGINT)"


def _greater(column: ColumnElement[float], value: ColumnElement[float]) -> ColumnElement[float]:
    """The larger of two numbers (SQLite's two-argument MAX, PostgreSQL's GREATEST)."""
    return case((value > column, value), else_=column)


def _clip_not_recording() -> ColumnElement[bool]:
    return events.c.clip_path.is_(None) | events.c.clip_s.is_not(None)


def _activity_cameras() -> Select[Any]:
    """The cameras that have activity rows, deleted cameras' too, found along the primary key
    (a skip scan: one lookup per camera, not a scan of the table)."""
    a = activity.c
    first = select(func.min(a.camera_id).label("id")).cte("c", recursive=True)
    following = select(func.min(a.camera_id)).where(a.camera_id > first.c.id)
    walk = first.union_all(select(following.scalar_subquery()).where(first.c.id.is_not(None)))
    return select(walk.c.id).where(walk.c.id.is_not(None))


def _inserted_id(conn: Connection, statement: Insert) -> int:
    key = conn.execute(statement).inserted_primary_key
    assert key is not None
    return int(key[0])


def _limit(limit: int) -> int:
    """A row limit both databases take: PostgreSQL's LIMIT is bound as a 32-bit integer,
    and neither could return more rows than that anyway; none below 0."""
    return min(max(limit, 0), 2**31 - 1)


def _chunks(ids: Iterable[int]) -> Iterator[list[int]]:
    """``ids`` that a row can have, ``CHUNK`` at a time."""
    valid = [i for i in ids if _is_row_id(i)]
    for start in range(0, len(valid), CHUNK):
        yield valid[start : start + CHUNK]


def _new_camera(
    name: str, source: str, method: str, min_area: float, sensitivity: float | None = None
) -> Insert:
    return insert(cameras).values(
        name=name,
        source=source,
        sensitivity=sensitivity,
        min_area=min_area,
        method=method,
        created_at=time.time(),
    )


def _camera(row: dict[str, Any]) -> dict[str, Any]:
    row["show_mask"] = bool(row["show_mask"])
    row["mask"] = json.loads(row["mask"])
    row["active"] = bool(row["active"])
    return row


def _event(row: dict[str, Any]) -> dict[str, Any]:
    row["boxes"] = json.loads(row["boxes"])
    row["track_ids"] = json.loads(row["track_ids"])
    return row


def _analysis(row: dict[str, Any]) -> dict[str, Any]:
    row["options"] = json.loads(row["options"])
    return row


def _target(row: dict[str, Any]) -> dict[str, Any]:
    row["cameras"] = None if row["cameras"] is None else json.loads(row["cameras"])
    return row


def _json_or_null(value: Sequence[int] | None) -> str | None:
    return None if value is None else json.dumps(list(value))


def _is_row_id(value: int) -> bool:
    """Whether a row id can be ``value`` (a 64-bit integer in both databases): beyond it no
    row has it, and binding it would fail."""
    return -(2**63) <= value < 2**63
