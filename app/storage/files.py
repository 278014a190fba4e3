"""Snapshots on disk (written whole or not at all), retention, and the streamed zip of a gallery."""

from __future__ import annotations

import contextlib
import errno
import io
import threading
import time
import zipfile
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, cast

from app.core.atomic import write_atomic

if TYPE_CHECKING:
    from app.storage.clips import ClipStore
    from app.storage.db import Database


WRITE_ERRORS = {
    errno.ENOSPC: "disk full",
    errno.EDQUOT: "disk quota exceeded",
    errno.EROFS: "read-only file system",
    errno.EACCES: "permission denied",
    errno.EPERM: "permission denied",
}

SnapshotsDeleted = Callable[[list[int]], None]
"""Is told the ids of snapshots just deleted: the server gives what tells every page (this
module knows no web)."""


def describe_write_error(exc: OSError) -> str:
    """A short reason for people (no paths: /api/health answers without a password)."""
    known = WRITE_ERRORS.get(exc.errno or 0)
    return known or f"cannot write ({exc.strerror or type(exc).__name__})"


def dated(camera_id: int, ts: float, suffix: str) -> str:
    """``<camera id>/<day>/<HHMMSSmmm><suffix>``: a camera's file of time ``ts`` (UTC)."""
    day = time.strftime("%Y-%m-%d", time.gmtime(ts))
    stamp = time.strftime("%H%M%S", time.gmtime(ts)) + f"{int(ts * 1000) % 1000:03d}"
    return f"{camera_id}/{day}/{stamp}{suffix}"


class CameraFiles:
    """Files under ``root``, kept by their path relative to it (the database keeps that),
    and per camera why the last write failed, until one succeeds: so a burst of failures
    is reported once and its end is noticed. ``kind`` names the files in messages."""

    kind = "file"

    def __init__(self, root: Path) -> None:
        self.root = root
        root.mkdir(parents=True, exist_ok=True)
        self._failures: dict[int, str] = {}
        self._lock = threading.Lock()

    def failed(self, camera_id: int, exc: OSError) -> str:
        """Note why a write for ``camera_id`` failed; the reason, for people."""
        reason = describe_write_error(exc)
        with self._lock:
            self._failures[camera_id] = reason
        return reason

    def written(self, camera_id: int) -> None:
        with self._lock:
            self._failures.pop(camera_id, None)

    def failure(self, camera_id: int) -> str | None:
        """Why the camera's last write failed; None once one succeeds."""
        with self._lock:
            return self._failures.get(camera_id)

    def path(self, relative: str) -> Path:
        resolved = (self.root / relative).resolve()
        if not resolved.is_relative_to(self.root.resolve()):
            raise ValueError(f"{self.kind} path outside the {self.kind} folder")
        return resolved

    def delete(self, relative: str) -> None:
        with contextlib.suppress(FileNotFoundError, NotADirectoryError):  # Already gone.
            self.path(relative).unlink()


class SnapshotStore(CameraFiles):
    """JPEG files under ``root/<camera id>/<day>/``. ``on_deleted`` is told of every
    snapshot deleted through it, by hand or by retention (a batch at a time) alike."""

    kind = "snapshot"

    def __init__(self, root: Path, on_deleted: SnapshotsDeleted | None = None) -> None:
        super().__init__(root)
        self.on_deleted = on_deleted

    def save(self, camera_id: int, ts: float, kind: str, data: bytes, event_id: int | None) -> str:
        """Write one JPEG, durably: the row the caller adds next must not outlive its file.

        Raises OSError (disk full, read-only...), after noting the reason.
        """
        relative = dated(camera_id, ts, f"-e{event_id or 0}-{kind}.jpg")
        try:
            write_atomic(self.root / relative, data, durable=True)
        except OSError as exc:
            self.failed(camera_id, exc)
            raise
        self.written(camera_id)
        return relative

    def delete_snapshots(self, db: Database, ids: list[int]) -> list[dict[str, Any]]:
        """Delete those of ``ids`` that exist and tell ``on_deleted`` their ids (nothing when
        none did); returns their rows.

        Rows go before files: a kill in between leaves a stray file, never a row without
        its picture.
        """
        deleted = db.delete_snapshots(ids)
        for row in deleted:
            self.delete(row["path"])
        if deleted and self.on_deleted is not None:
            self.on_deleted([row["id"] for row in deleted])
        return deleted


class _Sink:
    """A write-only, unseekable file: zipfile then writes data descriptors and never seeks."""

    def __init__(self) -> None:
        self.chunks: list[bytes] = []

    def write(self, data: bytes) -> int:
        self.chunks.append(bytes(data))
        return len(data)

    def flush(self) -> None:
        pass

    def take(self) -> bytes:
        out = b"".join(self.chunks)
        self.chunks.clear()
        return out


@dataclass(frozen=True)
class Fetched:
    """A file that is not here (another node keeps it), had whole when the zip reaches it."""

    fetch: Callable[[], bytes | None]
    """Its bytes, or None when they cannot be had (it is left out)."""
    mtime: float


def stream_zip(
    files: Iterable[tuple[Path | Fetched, str]], chunk_size: int = 1 << 16
) -> Iterator[bytes]:
    """Yield a zip of ``(path, name in archive)`` pairs piece by piece, never whole in memory.

    JPEGs are stored, not deflated: they do not compress, and storing is cheap.
    Files that vanished meanwhile (or cannot be fetched) are skipped.
    """
    sink = _Sink()
    target = cast(IO[bytes], sink)
    with zipfile.ZipFile(target, mode="w", compression=zipfile.ZIP_STORED) as archive:
        for source, name in files:
            try:
                if isinstance(source, Fetched):
                    data = source.fetch()
                    if data is None:
                        continue
                    handle: IO[bytes] = io.BytesIO(data)
                    mtime = source.mtime
                else:
                    handle = source.open("rb")
                    mtime = source.stat().st_mtime
            except OSError:
                continue
            with handle:
                info = zipfile.ZipInfo(name, date_time=time.gmtime(mtime)[:6])
                info.compress_type = zipfile.ZIP_STORED
                with archive.open(info, mode="w") as entry:
                    while block := handle.read(chunk_size):
                        entry.write(block)
                        if sink.chunks:
                            yield sink.take()
            if sink.chunks:
                yield sink.take()
    if sink.chunks:
        yield sink.take()


def prune(
    db: Database,
    store: SnapshotStore,
    before: float,
    batch: int = 1000,
    clips: ClipStore | None = None,
) -> int:
    """Delete snapshots (rows and files), finished events with their clips, and the
    activity history older than ``before``; how many snapshots and clips went."""
    removed = 0
    while True:
        rows = db.snapshots(until=before, limit=batch)
        rows = [r for r in rows if r["ts"] < before]
        if not rows:
            break
        removed += len(store.delete_snapshots(db, [r["id"] for r in rows]))
    clip_paths = db.delete_events_before(before)
    if clips is not None:
        for relative in clip_paths:
            clips.delete(relative)
    return removed + len(clip_paths)


RETENTION = "deleted to stay under VIGIL_RETENTION_MB"
"""An event's ``clip_error`` once the size cap has taken its clip."""


def prune_to_size(
    db: Database,
    store: SnapshotStore,
    max_bytes: int,
    batch: int = 500,
    clips: ClipStore | None = None,
) -> int:
    """Delete the oldest snapshots and clips until they total at most ``max_bytes``; returns
    how many.

    Oldest first, snapshots by their time and clips by their event's start, whichever is
    older; a clip still being recorded stays. The running totals in the database say when
    to stop, so a store under its cap costs two queries. An ended event goes with its last
    snapshot and clip.
    """
    removed = 0
    while (excess := db.snapshot_bytes() + db.clip_bytes() - max_bytes) > 0:
        candidates: list[tuple[float, int, str, int]] = [
            (row["ts"], row["id"], "snapshot", row["size"]) for row in db.oldest_snapshots(batch)
        ]
        if clips is not None:
            candidates += [
                (row["started_at"], row["id"], "clip", row["clip_bytes"])
                for row in db.oldest_clips(batch)
            ]
        candidates.sort()
        chosen: dict[str, list[int]] = {"snapshot": [], "clip": []}
        for _, row_id, kind, size in candidates[:batch]:
            chosen[kind].append(row_id)
            excess -= size
            if excess <= 0:
                break
        if not chosen["snapshot"] and not chosen["clip"]:
            break
        events: set[int] = set()
        if chosen["snapshot"]:
            deleted = store.delete_snapshots(db, chosen["snapshot"])
            removed += len(deleted)
            events.update(r["event_id"] for r in deleted if r["event_id"] is not None)
        if clips is not None:
            for event_id in chosen["clip"]:
                event = db.event(event_id)
                if event is not None and event["clip_path"]:
                    db.drop_clip(event_id, RETENTION)
                    clips.delete(event["clip_path"])
                    removed += 1
                    events.add(event_id)
        db.delete_events_without_snapshots(sorted(events))
    return removed
