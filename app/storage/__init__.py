"""Persistence: the SQLite database, the snapshot files and the event clips."""

from app.storage.clips import ClipStore
from app.storage.db import Database
from app.storage.files import SnapshotStore, prune, prune_to_size, stream_zip, write_atomic

__all__ = [
    "ClipStore",
    "Database",
    "SnapshotStore",
    "prune",
    "prune_to_size",
    "stream_zip",
    "write_atomic",
]
