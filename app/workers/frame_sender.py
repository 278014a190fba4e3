"""A camera process's sending of frames to the server, made only while someone watches.

``Link`` is the process's end of its pipe to the server; ``FrameSender`` makes and sends
each watched camera's newest frame: the annotated picture for MJPEG viewers and the
histogram over the pipe, the /ws/live message over the live pipe
(``app.workers.live_pipe``).
"""

from __future__ import annotations

import contextlib
import logging
import threading
from multiprocessing.connection import Connection
from typing import Any, cast

from app.workers.hub import Kind, LiveFrame, Picture
from app.workers.live_pipe import LivePipeWriter

log = logging.getLogger("vigil.cameras")


class Link:
    """The camera process's end of the pipe: sends are whole messages, from any thread."""

    def __init__(self, conn: Connection) -> None:
        self._conn = conn
        self._lock = threading.Lock()

    def send(self, item: tuple[Any, ...]) -> None:
        with self._lock, contextlib.suppress(OSError, ValueError):  # The server is gone.
            self._conn.send(item)


class FrameSender:
    """Encodes the newest frame of each watched camera and sends it to the server: the
    annotated picture for MJPEG viewers, the histogram, the /ws/live message (the
    camera's own JPEG where it sent one, and the detections as data), each only while
    someone watches it.

    One thread for the process. A frame replaced by a newer one before its turn is
    skipped, so a slow pipe costs frames, never delay. A JPEG camera's /ws/live message
    costs only its header: the camera's thread writes it to the live pipe itself
    (``app.workers.live_pipe``), as soon as the frame is published.
    """

    def __init__(self, link: Link, live: LivePipeWriter | None = None) -> None:
        self._link = link
        self._live = live
        self._generations: dict[int, int] = {}
        self._watching: dict[int, dict[Kind, int]] = {}
        self._widths: dict[int, int] = {}
        """Per camera, the widest picture a /ws/live client needs (0: any)."""
        self._pending: dict[int, LiveFrame] = {}
        self._wake = threading.Condition()
        self._stopped = False
        self._thread = threading.Thread(target=self._run, name="frame-sender", daemon=True)
        self._thread.start()

    def start(self, camera_id: int, generation: int) -> None:
        """A (new) worker for ``camera_id``: nothing watched until the server says so."""
        with self._wake:
            self._generations[camera_id] = generation
            self._watching.pop(camera_id, None)
            self._pending.pop(camera_id, None)

    def watch(
        self, camera_id: int, generation: int, counts: dict[Kind, int], live_width: int = 0
    ) -> None:
        with self._wake:
            if self._generations.get(camera_id) == generation:
                self._watching[camera_id] = counts
                self._widths[camera_id] = live_width

    def offer(self, camera_id: int, item: Picture) -> None:
        frame = cast(LiveFrame, item)  # A worker's own frames.
        with self._wake:
            counts = self._watching.get(camera_id)
            if not counts or not any(counts.values()):
                return
            live = counts.get("live", 0) > 0 and self._live is not None
            inline = live and frame.source.jpeg is not None  # Only a header to make.
            if not inline or counts.get("picture") or counts.get("histogram"):
                self._pending[camera_id] = frame
                self._wake.notify()
            width = self._widths.get(camera_id, 0)
            generation = self._generations.get(camera_id, 0)
        if inline:
            self._send_live(camera_id, generation, frame, width)

    def _send_live(self, camera_id: int, generation: int, item: LiveFrame, width: int) -> None:
        assert self._live is not None
        try:
            message = item.live(camera_id, width)
        except Exception:  # One bad frame must not stop the camera.
            log.exception("camera %s: cannot make a live frame", camera_id)
            return
        self._live.write(camera_id, generation, message)

    def stop(self) -> None:
        with self._wake:
            self._stopped = True
            self._wake.notify()

    def _run(self) -> None:
        while True:
            with self._wake:
                self._wake.wait_for(lambda: self._pending or self._stopped)
                if self._stopped:
                    return
                pending, self._pending = self._pending, {}
                watching = {cid: dict(self._watching.get(cid, {})) for cid in pending}
                widths = {cid: self._widths.get(cid, 0) for cid in pending}
                generations = {cid: self._generations.get(cid, 0) for cid in pending}
            for camera_id, item in pending.items():
                counts = watching[camera_id]
                generation = generations[camera_id]
                if counts.get("live") and self._live is not None and item.source.jpeg is None:
                    self._send_live(camera_id, generation, item, widths[camera_id])
                if not counts.get("picture") and not counts.get("histogram"):
                    continue
                try:
                    picture = item.jpeg() if counts.get("picture") else None
                    histogram = item.histogram_jpeg() if counts.get("histogram") else None
                except Exception:  # One bad frame must not stop every camera's pictures.
                    log.exception("camera %s: cannot encode a frame", camera_id)
                    continue
                self._link.send(("frame", camera_id, generation, picture, histogram))
