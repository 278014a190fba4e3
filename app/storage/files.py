"""Snapshots on disk (written whole or not at all) and the streamed zip of a gallery."""

from __future__ import annotations

import time
import zipfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO, TYPE_CHECKING, cast

from app.core.atomic import write_atomic

if TYPE_CHECKING:
    from app.storage.db import Database


class SnapshotStore:
    """JPEG files under ``root/<camera id>/<day>/``; the database keeps paths relative to root."""

    def __init__(self, root: Path) -> None:
        self.root = root
        root.mkdir(parents=True, exist_ok=True)

    def save(self, camera_id: int, ts: float, kind: str, data: bytes, event_id: int | None) -> str:
        day = time.strftime("%Y-%m-%d", time.gmtime(ts))
        stamp = time.strftime("%H%M%S", time.gmtime(ts)) + f"{int(ts * 1000) % 1000:03d}"
        name = f"{stamp}-e{event_id or 0}-{kind}.jpg"
        relative = f"{camera_id}/{day}/{name}"
        write_atomic(self.root / relative, data)
        return relative

    def path(self, relative: str) -> Path:
        resolved = (self.root / relative).resolve()
        if not resolved.is_relative_to(self.root.resolve()):
            raise ValueError("snapshot path outside the snapshot folder")
        return resolved

    def delete(self, relative: str) -> None:
        self.path(relative).unlink(missing_ok=True)


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


def stream_zip(files: Iterable[tuple[Path, str]], chunk_size: int = 1 << 16) -> Iterator[bytes]:
    """Yield a zip of ``(path, name in archive)`` pairs piece by piece, never whole in memory.

    JPEGs are stored, not deflated: they do not compress, and storing is cheap.
    Files that vanished meanwhile are skipped.
    """
    sink = _Sink()
    target = cast(IO[bytes], sink)
    with zipfile.ZipFile(target, mode="w", compression=zipfile.ZIP_STORED) as archive:
        for path, name in files:
            try:
                handle = path.open("rb")
            except OSError:
                continue
            with handle:
                info = zipfile.ZipInfo(name, date_time=time.gmtime(path.stat().st_mtime)[:6])
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


def prune(db: Database, store: SnapshotStore, before: float, batch: int = 1000) -> int:
    """Delete snapshots (rows and files) and finished events older than ``before``."""
    removed = 0
    while True:
        rows = db.snapshots(until=before, limit=batch)
        rows = [r for r in rows if r["ts"] < before]
        if not rows:
            break
        for row in db.delete_snapshots([r["id"] for r in rows]):
            store.delete(row["path"])
            removed += 1
    db.delete_events_before(before)
    return removed
