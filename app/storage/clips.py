"""Event clips on disk: where they go, how a clip cut short is made whole, and their retention.

A clip is a fragmented MP4 (``app.recording.mp4``): ``ftyp``, an empty ``moov``, then a
``moof`` and its ``mdat`` per second or so, and an ``mfra`` index once finished. Each
fragment reaches the file as it is made, so a process killed while recording leaves a
clip that plays up to its last whole fragment; ``repair`` cuts off the half-written one
after it (a browser would stop on it with a decode error) and the database learns the
clip's length on the next start.
"""

from __future__ import annotations

import contextlib
import logging
import os
import struct
from pathlib import Path
from typing import TYPE_CHECKING, Any

import av

from app.storage.files import CameraFiles, dated

if TYPE_CHECKING:
    from app.storage.db import Database

log = logging.getLogger("vigil.clips")

HEADER = struct.Struct(">I4s")
"""A box's size (32 bits, whole box) and type; size 1: a 64-bit size follows."""
LARGE = struct.Struct(">Q")

KILLED = "recording stopped early: the camera's process ended"


class ClipStore(CameraFiles):
    """MP4 files under ``root/<camera id>/<day>/``; as ``SnapshotStore`` does for pictures,
    it remembers per camera why the last clip could not be written, until one is."""

    kind = "clip"

    def create(self, camera_id: int, ts: float, event_id: int) -> tuple[str, Path]:
        """A new clip's relative path and its folder made; OSError (noted) if the disk refuses."""
        relative = dated(camera_id, ts, f"-e{event_id}.mp4")
        path = self.root / relative
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            self.failed(camera_id, exc)
            raise
        return relative, path

    def delete(self, relative: str) -> None:
        with contextlib.suppress(ValueError):  # A path from elsewhere: nothing of ours.
            super().delete(relative)


def complete_length(path: Path) -> int:
    """How many bytes from the start of the MP4 at ``path`` are whole boxes ending with a
    whole fragment (``moof`` and its ``mdat``), or with its ``moov`` when it has no fragment
    yet; 0 when not even that is there. A clip being written is served this far."""
    try:
        size = path.stat().st_size
        handle = path.open("rb")
    except OSError:
        return 0
    good = 0
    at = 0
    with handle:
        while at + HEADER.size <= size:
            handle.seek(at)
            box_size, kind = HEADER.unpack(handle.read(HEADER.size))
            if box_size == 1:
                box_size = LARGE.unpack(handle.read(LARGE.size))[0]
            elif box_size == 0:  # To the end of the file: only a finished file ends so.
                box_size = size - at
            if box_size < HEADER.size or at + box_size > size:
                break  # Half written.
            at += box_size
            if kind in (b"moov", b"mdat", b"mfra"):
                good = at
    return good


def repair(path: Path) -> int:
    """Cut a clip killed while being written back to its last whole fragment; its length in
    bytes then (0: nothing playable is left, the file is removed)."""
    good = complete_length(path)
    try:
        if good <= 0:
            path.unlink(missing_ok=True)
            return 0
        if path.stat().st_size != good:
            with path.open("r+b") as handle:
                handle.truncate(good)
                handle.flush()
                os.fsync(handle.fileno())
    except OSError:
        log.exception("cannot repair clip %s", path)
        return 0
    return good


def clip_length_s(path: Path) -> float:
    """The clip's length in seconds, from its packets' times (no decoding): from its first
    frame to its last, and the last one's own length; 0 without a frame."""
    try:
        with av.open(str(path)) as container:
            stream = container.streams.video[0]
            first: int | None = None
            end = 0
            for packet in container.demux(stream):
                if packet.pts is None:
                    continue
                first = packet.pts if first is None else min(first, packet.pts)
                end = max(end, packet.pts + (packet.duration or 0))
            if first is None or stream.time_base is None:
                return 0.0
            return float((end - first) * stream.time_base)
    except (av.FFmpegError, IndexError, OSError):
        return 0.0


def finish_unfinished(db: Database, store: ClipStore, camera_id: int | None = None) -> int:
    """Finish the clips whose recording a killed process left unfinished (all, or one
    camera's): each is cut back to its last whole fragment and its size and length noted;
    one with no whole fragment goes. How many clips were finished or dropped."""
    done = 0
    for event in db.unfinished_clips(camera_id):
        try:
            path = store.path(event["clip_path"])
        except ValueError:
            db.drop_clip(event["id"], KILLED)
            continue
        size = repair(path)
        length = clip_length_s(path) if size else 0.0
        if size and length > 0:
            db.finish_clip(event["id"], size, round(length, 3), KILLED)
        else:
            store.delete(event["clip_path"])
            db.drop_clip(event["id"], KILLED)
        done += 1
    if done:
        log.info("finished %d clip(s) left unfinished when a camera process ended", done)
    return done


def delete_clips(db: Database, store: ClipStore, events: list[dict[str, Any]], why: str) -> int:
    """Delete these events' clips (rows first: a kill in between leaves a stray file, never
    a row without its clip); how many there were."""
    deleted = 0
    for event in events:
        if event.get("clip_path"):
            db.drop_clip(event["id"], why)
            store.delete(event["clip_path"])
            deleted += 1
    return deleted
