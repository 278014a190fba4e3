"""Persistence: the SQLite database and the snapshot files."""

from app.storage.db import Database
from app.storage.files import SnapshotStore, prune, prune_to_size, stream_zip, write_atomic

__all__ = ["Database", "SnapshotStore", "prune", "prune_to_size", "stream_zip", "write_atomic"]
