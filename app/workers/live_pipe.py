"""The pipe that carries /ws/live messages from a camera process to the server.

Live frames have a pipe of their own, beside the one of commands, messages and MJPEG
pictures, so that a frame costs as few wake-ups as can be: a camera thread that has
just read a JPEG frame writes its message itself (no hand-over to another thread), and
in the server the event loop reads the pipe (no receiving thread, no hand-over to the
loop), then hands the bytes to the /ws/live clients, which the loop serves anyway.
Measured at 25 fps (``bench/bench_cameras.py``), each hand-over of a frame between
threads cost 0.05 to 0.15 ms of CPU, as a process woken for it finds its caches cold.

A message on the pipe: a 16-byte head (the message's length, the worker's generation and
the camera id, big-endian), then the /ws/live message. A writer never blocks: a message
that does not fit in the pipe now is dropped (the next frame is newer anyway), so a
server that falls behind costs frames, never a camera's time.
"""

from __future__ import annotations

import array
import asyncio
import contextlib
import fcntl
import logging
import os
import struct
import termios
import threading
from collections.abc import Callable
from multiprocessing.connection import Connection

log = logging.getLogger("vigil.cameras")

HEAD = struct.Struct(">IqI")
"""A message's length, its worker's generation, its camera id."""
PIPE_BYTES = 1 << 20
"""The pipe's capacity asked for (Linux's default limit for an unprivileged process):
about 25 frames of a 640x480 camera."""
ROOM = 64 * 1024
"""Room kept free beyond a message: a pipe holds pages, and a message's last one is part
empty."""
F_SETPIPE_SZ = 1031
READ_BYTES = 1 << 20

Deliver = Callable[[int, int, bytes], None]
"""Called with (camera id, generation, message) for each message read."""


class LivePipeWriter:
    """The camera process's end: ``write`` from any thread, never blocking."""

    def __init__(self, conn: Connection) -> None:
        self._conn = conn  # Kept: its file descriptor lives as long as it does.
        self._fd = conn.fileno()
        try:
            self.capacity = fcntl.fcntl(self._fd, F_SETPIPE_SZ, PIPE_BYTES)
        except OSError:  # Not Linux, or the limit is lower: the pipe as it is.
            self.capacity = 64 * 1024
        os.set_blocking(self._fd, False)
        self._lock = threading.Lock()
        self._queued = array.array("i", [0])
        self.dropped = 0

    def write(self, camera_id: int, generation: int, message: bytes) -> bool:
        """Whether the message went into the pipe (False: no room now, or the server is
        gone)."""
        head = HEAD.pack(len(message), generation, camera_id)
        size = len(head) + len(message)
        with self._lock:
            try:
                fcntl.ioctl(self._fd, termios.FIONREAD, self._queued, True)
                if self._queued[0] + size + ROOM > self.capacity:
                    self.dropped += 1
                    return False
                written = os.writev(self._fd, (head, message))
                if written < size:  # Not seen: there was room. A message is whole.
                    os.set_blocking(self._fd, True)
                    try:
                        os.write(self._fd, (head + message)[written:])
                    finally:
                        os.set_blocking(self._fd, False)
            except (BlockingIOError, BrokenPipeError, OSError):
                return False
        return True

    def close(self) -> None:
        self._conn.close()


class LivePipeReader:
    """The server's end: read by the event loop ``loop`` when there is one (the server's),
    else by a thread of its own; ``deliver`` gets each message whole, in that thread.
    Ends when the camera process is gone (end of file) or on ``close``."""

    def __init__(
        self, conn: Connection, deliver: Deliver, loop: asyncio.AbstractEventLoop | None
    ) -> None:
        self._conn = conn
        self._fd = conn.fileno()
        self._deliver = deliver
        self._loop = loop
        self._buffer = bytearray()
        self._chunk = memoryview(bytearray(READ_BYTES))
        """Where each read lands: a bytes object of READ_BYTES made for every read cost
        a mapping of fresh pages and its unmapping, at every frame."""
        self._closed = False
        if loop is not None:
            os.set_blocking(self._fd, False)
            loop.call_soon_threadsafe(self._attach)
        else:
            threading.Thread(target=self._read_forever, name="live-frames", daemon=True).start()

    def _attach(self) -> None:
        assert self._loop is not None
        if not self._closed:
            self._loop.add_reader(self._fd, self._readable)

    def _readable(self) -> None:
        """What the pipe holds now; at its end (the camera process gone), stop."""
        try:
            read = os.readv(self._fd, [self._chunk])
        except BlockingIOError:
            return
        except OSError:
            read = 0
        if read:
            self._feed(self._chunk[:read])
        else:
            self._detach()

    def _read_forever(self) -> None:
        while not self._closed:
            self._readable()

    def _feed(self, data: memoryview) -> None:
        buffer = self._buffer
        buffer += data
        view = memoryview(buffer)
        at = 0
        while len(buffer) - at >= HEAD.size:
            length, generation, camera_id = HEAD.unpack_from(buffer, at)
            end = at + HEAD.size + length
            if end > len(buffer):
                break
            message = bytes(view[at + HEAD.size : end])
            at = end
            try:
                self._deliver(camera_id, generation, message)
            except Exception:  # One client's failure must not stop every camera's frames.
                log.exception("camera %s: a live frame could not be handed on", camera_id)
        view.release()  # A bytearray with a view of it cannot shrink.
        del buffer[:at]

    def _detach(self) -> None:
        if self._loop is not None and not self._closed:
            with contextlib.suppress(ValueError, OSError):
                self._loop.remove_reader(self._fd)
        self._closed = True
        self._conn.close()

    def close(self) -> None:
        """Stop reading (from any thread)."""
        if self._loop is None:
            self._closed = True
            return
        with contextlib.suppress(RuntimeError):  # The loop is closed already.
            self._loop.call_soon_threadsafe(self._detach)
