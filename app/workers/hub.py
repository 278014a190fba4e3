"""The latest frame of a camera, and waiting for the next one from async code.

A worker publishes a ``LiveFrame`` per frame: the source's frame and what was
found in it. Nothing is decoded, drawn or encoded then. The first viewer that
wants a frame's JPEG draws and encodes it, and every other viewer gets those
bytes: one encode per frame whatever the number of viewers, none without
viewers. With nothing to draw, a camera's own JPEG is passed on as it came.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal, Protocol

import cv2
import numpy as np

from app.sources.frames import SourceFrame
from app.vision.annotate import Annotator, overlay_mask
from app.vision.detections import Detection
from app.vision.histogram import GreyStats, grey_histogram, grey_stats, render_histogram
from app.vision.types import GrayImage, Image, Mask
from app.workers.live_frames import live_message

Kind = Literal["picture", "histogram", "live"]
"""What a viewer watches: the (annotated) picture, the grey-level histogram, or live frames
(``/ws/live``: the camera's picture as it is, with what was found as data,
``app.workers.live_frames``)."""

HISTOGRAM_WIDTH = 320
"""A histogram needs no more pixels than this (a JPEG is decoded at reduced scale)."""

ANNOTATOR = Annotator()
"""One annotator for every camera: it holds no state."""


class EncodeCounter:
    """How many JPEGs a worker encoded (for tests and the benchmark)."""

    def __init__(self) -> None:
        self.frames = 0
        self.histograms = 0


@dataclass(eq=False)
class LiveFrame:
    seq: int
    ts: float
    source: SourceFrame
    detections: Sequence[Detection] = ()
    trails: Mapping[int, Sequence[tuple[float, float]]] | None = None
    mask: Mask | None = None
    gray: GrayImage | None = None
    stats: GreyStats | None = None
    quality: int = 80
    counter: EncodeCounter | None = None
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)
    _jpeg: bytes | None = None
    _histogram: bytes | None = None
    _live: tuple[int, int, bytes] | None = None
    """The /ws/live message made, with the camera id and width it was made for."""

    def has(self, kind: Kind) -> bool:
        return True  # Made on demand, any kind.

    def annotated(self) -> Image:
        picture = self.source.image()
        if self.mask is not None:
            picture = overlay_mask(picture, self.mask)
        if self.detections or self.trails:
            picture = ANNOTATOR(picture, self.detections, self.trails)
        return picture

    def made(self, kind: Kind) -> bytes | None:
        # Without the lock: an event loop asks, while another viewer may hold it for a
        # whole encode. A field read is whole, and what is drawn was fixed at publish.
        if kind == "histogram":
            return self._histogram
        if kind == "live":
            live = self._live
            return live[2] if live is not None else None
        jpeg = self._jpeg
        return jpeg if jpeg is not None else self._passed_on()

    def jpeg(self) -> bytes:
        with self._lock:
            if self._jpeg is None:
                passed_on = self._passed_on()
                if passed_on is not None:
                    self._jpeg = passed_on
                else:
                    self._jpeg = encode_jpeg(self.annotated(), self.quality)
                    if self.counter is not None:
                        self.counter.frames += 1
            return self._jpeg

    def live(self, camera_id: int, width: int) -> bytes:
        """The frame's /ws/live message (``app.workers.live_frames``), made once."""
        with self._lock:
            made = self._live
            if made is None or made[:2] != (camera_id, width):
                message = live_message(
                    camera_id,
                    self.seq,
                    self.ts,
                    self.source,
                    self.detections,
                    self.trails,
                    self.mask,
                    width,
                    self.quality,
                )
                made = self._live = (camera_id, width, message)
            return made[2]

    def _passed_on(self) -> bytes | None:
        """The camera's own JPEG where nothing is drawn on the frame."""
        untouched = self.mask is None and not self.detections and not self.trails
        return self.source.jpeg if untouched else None

    def histogram_jpeg(self) -> bytes:
        with self._lock:
            if self._histogram is None:
                gray = self.gray if self.gray is not None else self.source.gray(HISTOGRAM_WIDTH)
                stats = self.stats or grey_stats(gray)
                picture = render_histogram(grey_histogram(gray), stats, 256, 120)
                self._histogram = encode_jpeg(picture, 85)
                if self.counter is not None:
                    self.counter.histograms += 1
            return self._histogram


def encode_jpeg(image: Image | np.ndarray, quality: int = 80) -> bytes:
    ok, buffer = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    return buffer.tobytes()


class Picture(Protocol):
    """What a hub holds for viewers: a camera's frame in process (``LiveFrame``), or the
    JPEGs a camera process sent (``SentFrame``)."""

    @property
    def seq(self) -> int: ...

    def has(self, kind: Kind) -> bool:
        """Whether this frame carries a picture of ``kind``."""
        ...

    def made(self, kind: Kind) -> bytes | None:
        """The ``kind`` JPEG where getting it takes no work (encoded already, or the
        camera's own passed on), else None."""
        ...

    def jpeg(self) -> bytes: ...

    def histogram_jpeg(self) -> bytes: ...


async def viewer_jpeg(item: Picture, kind: Kind) -> bytes:
    """``item``'s ``kind`` JPEG for a viewer on an event loop: at once where it is made,
    else drawn and encoded on a worker thread, off the loop. (A thread's round trip costs
    about 0.3 ms of CPU a frame here; most frames a viewer gets are made.)"""
    made = item.made(kind)
    if made is not None:
        return made
    return await asyncio.to_thread(item.histogram_jpeg if kind == "histogram" else item.jpeg)


@dataclass(frozen=True, slots=True)
class SentFrame:
    """A frame a camera process encoded for this process's viewers."""

    seq: int
    picture: bytes | None
    histogram: bytes | None

    def has(self, kind: Kind) -> bool:
        return self.made(kind) is not None

    def made(self, kind: Kind) -> bytes | None:
        if kind == "live":
            return None  # Live messages come apart (``FrameHub.offer_live``).
        return self.picture if kind == "picture" else self.histogram

    def jpeg(self) -> bytes:
        return self.picture or b""

    def histogram_jpeg(self) -> bytes:
        return self.histogram or b""


class LiveSink(Protocol):
    """A /ws/live client: takes each frame's message, newest first (``app.api.routes.live``)."""

    def offer(self, key: int, message: bytes) -> None:
        """The newest message of camera ``key``; called from the thread that publishes."""
        ...

    def wake(self, resync: bool = False) -> None:
        """Something changed besides frames; ``resync``: the camera is going away."""
        ...


class FrameHub:
    """Holds the newest picture; async viewers wait for one newer than what they have.

    Viewers register with ``watch(kind)``; ``on_watch`` hears every change of the
    counts (a camera process sends only what is watched). A /ws/live client registers
    with ``watch_live``: each frame's live message is handed to it as it comes
    (``offer_live``), and ``live_width`` is the widest picture any such client asked for.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._latest: Picture | None = None
        self._waiters: set[tuple[asyncio.AbstractEventLoop, asyncio.Event]] = set()
        self._sinks: dict[LiveSink, tuple[int, int]] = {}
        """Each /ws/live client's key (its camera id) and the width it asked for."""
        self.watching: dict[Kind, int] = {"picture": 0, "histogram": 0, "live": 0}
        self.live_width = 0
        self.on_watch: Callable[[dict[Kind, int]], None] | None = None
        self.on_publish: Callable[[Picture], None] | None = None
        self.closed = False

    @property
    def viewers(self) -> int:
        return sum(self.watching.values())

    @contextlib.contextmanager
    def watch(self, kind: Kind) -> Iterator[None]:
        self._count(kind, 1)
        try:
            yield
        finally:
            self._count(kind, -1)

    def _count(self, kind: Kind, step: int) -> None:
        with self._lock:
            self.watching[kind] += step
            counts = dict(self.watching)
        if self.on_watch is not None:
            self.on_watch(counts)

    def watch_live(self, sink: LiveSink, key: int, width: int) -> None:
        """``sink`` gets every frame's live message from now on (again: with a new width)."""
        with self._lock:
            added = sink not in self._sinks
            self._sinks[sink] = (key, width)
            changed = self._set_live_width()
        if added:
            self._count("live", 1)
        elif changed and self.on_watch is not None:
            self.on_watch(dict(self.watching))

    def unwatch_live(self, sink: LiveSink) -> None:
        with self._lock:
            if self._sinks.pop(sink, None) is None:
                return
            self._set_live_width()
        self._count("live", -1)

    def _set_live_width(self) -> bool:
        """The widest picture a client asked for (under the lock); whether it changed."""
        width = max((w for _, w in self._sinks.values()), default=0)
        changed, self.live_width = width != self.live_width, width
        return changed

    @property
    def latest(self) -> Picture | None:
        return self._latest

    def publish(self, item: Picture) -> None:
        if self.on_publish is not None:
            self.on_publish(item)
        with self._lock:
            self._latest = item
            waiters = list(self._waiters)
        for loop, event in waiters:
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(event.set)

    def offer_live(self, message: bytes) -> None:
        """A frame's /ws/live message, for every live client (it is not ``latest``: the
        MJPEG viewers' frames come apart, and must not be taken for this)."""
        with self._lock:
            sinks = list(self._sinks.items())
        for sink, (key, _) in sinks:
            sink.offer(key, message)

    def close(self) -> None:
        """Wake every waiting viewer with None (the camera is going away)."""
        with self._lock:
            self.closed = True
            waiters = list(self._waiters)
            sinks = list(self._sinks)
        for loop, event in waiters:
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(event.set)
        for sink in sinks:
            sink.wake(resync=True)

    async def next(self, after_seq: int, timeout: float, kind: Kind = "picture") -> Picture | None:
        """A frame newer than ``after_seq`` with a ``kind`` picture, or None after ``timeout``."""
        event = asyncio.Event()
        key = (asyncio.get_running_loop(), event)
        with self._lock:
            self._waiters.add(key)
        try:
            deadline = time.monotonic() + timeout
            while True:
                event.clear()
                if self.closed:
                    return None
                latest = self._latest
                if latest is not None and latest.seq > after_seq and latest.has(kind):
                    return latest
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                # A timeout scope rather than wait_for, which wraps the wait in a task.
                with contextlib.suppress(TimeoutError):
                    async with asyncio.timeout(remaining):
                        await event.wait()
        finally:
            with self._lock:
                self._waiters.discard(key)
