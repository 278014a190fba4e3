"""Atomic file writes: a reader (or a crash) never leaves half a file behind."""

from __future__ import annotations

import os
import secrets
from pathlib import Path


def write_atomic(path: Path, data: bytes, durable: bool = False) -> None:
    """Write to a temporary name in the same folder, then rename over ``path`` (with the
    mode a plain open() gives a new file: ``_create_beside``).

    A killed process leaves the old file or the new one either way. ``durable``
    also survives a power cut: the data reaches the disk before the rename, and
    the rename before the call returns, so a database row written next never
    names a file the disk does not hold. Not for files rewritten many times a
    second (each fsync waits for the disk).
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = _create_beside(path)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            if durable:
                handle.flush()
                os.fsync(handle.fileno())
        tmp.replace(path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    if durable:
        _fsync_folder(path.parent)


def _create_beside(path: Path) -> tuple[int, Path]:
    """A new, empty file under an unused name in ``path``'s folder, open for writing. It
    is created as a plain open() creates one, the kernel taking the umask off 0666
    (mkstemp's 0600 would keep the outputs from all but their writer)."""
    while True:
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(6)}.tmp")
        try:
            return os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666), tmp
        except FileExistsError:
            continue  # Another writer drew the same name: draw again.


def _fsync_folder(folder: Path) -> None:
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
