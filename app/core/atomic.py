"""Atomic file writes: a reader (or a crash) never leaves half a file behind."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

# Read once, at import (setting it is the only way to read it, and it is the process's):
# files written here get the mode a plain open() would give them, not mkstemp's 0600.
_UMASK = os.umask(0o022)
os.umask(_UMASK)
FILE_MODE = 0o666 & ~_UMASK


def write_atomic(path: Path, data: bytes, durable: bool = False) -> None:
    """Write to a temporary name in the same folder, then rename over ``path`` (with the
    mode a plain open() gives a new file: ``FILE_MODE``).

    A killed process leaves the old file or the new one either way. ``durable``
    also survives a power cut: the data reaches the disk before the rename, and
    the rename before the call returns, so a database row written next never
    names a file the disk does not hold. Not for files rewritten many times a
    second (each fsync waits for the disk).
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, FILE_MODE)
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            if durable:
                handle.flush()
                os.fsync(handle.fileno())
        Path(tmp).replace(path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    if durable:
        _fsync_folder(path.parent)


def _fsync_folder(folder: Path) -> None:
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
