"""H.264 in fragmented MP4, through PyAV's libx264: event clips and ``annotated.mp4``.

Fragmented (``frag_keyframe+empty_moov``): the ``moov`` at the start holds no samples,
and a ``moof`` and ``mdat`` follow per keyframe, a keyframe a second. Each fragment goes
to the file as soon as it is made, so a browser plays a clip while it is being
recorded, and a process killed mid-clip leaves one that plays up to its last whole
fragment (``app.storage.clips.repair``). Chromium plays it, seeks in it and knows its
length (from the ``mfra`` index written at the end, or by reading the fragments).

Frames come as the camera has them (``ClipFrame``): a JPEG camera's own JPEG, decoded by
libavcodec's MJPEG decoder straight into YUV (4:2:0 JPEGs need no conversion at all: the
clip is then full-range YUV, as the JPEGs are), or a decoded frame kept as I420. Times
are the real ones (90 kHz), so a camera that drops frames gives a clip that does too,
at the right moments. H.264 4:2:0 needs even sides: an odd-sized frame is scaled one
pixel larger.
"""

from __future__ import annotations

import contextlib
import os
import queue
import threading
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any, BinaryIO, cast

import av
import av.video.frame
import cv2
import numpy as np

from app.vision.types import Image

U8Array = np.ndarray[Any, np.dtype[np.uint8]]

TIME_BASE = Fraction(1, 90000)
MOVFLAGS = "frag_keyframe+empty_moov+default_base_moof"
KEYFRAME_S = 1.0
"""A keyframe, and so a fragment, about this often: what a kill can lose at most, and the
steps a browser seeks by."""


@dataclass(frozen=True)
class EncoderSettings:
    """libx264's settings (``VIGIL_CLIP_PRESET``, ``VIGIL_CLIP_CRF``): chosen by the CPU
    per frame ``bench/bench_recording.py`` measures. One thread: each clip has its own
    thread already, and x264's frame threads would hold frames back (a later fragment)."""

    preset: str = "ultrafast"
    crf: int = 26
    threads: int = 1


@dataclass(frozen=True, slots=True)
class ClipFrame:
    """One frame for a clip, as cheap to keep as the camera allows: ``jpeg`` (the camera's
    own bytes) or ``i420`` (a decoded frame converted, half the size of BGR), or ``bgr``
    (a decoded frame of odd size, which I420 cannot hold)."""

    mono: float
    """``time.monotonic()`` when it came: the clip's times."""
    wall: float
    """``time.time()`` when it came: when the clip starts, for people."""
    size: tuple[int, int]
    jpeg: bytes | None = None
    pixels: np.ndarray | None = None
    """I420 (height * 3 / 2 rows) or, for an odd size, BGR."""

    @property
    def nbytes(self) -> int:
        if self.jpeg is not None:
            return len(self.jpeg)
        return 0 if self.pixels is None else int(self.pixels.nbytes)


def decoded_clip_frame(image: Image, mono: float, wall: float) -> ClipFrame:
    """A decoded (BGR) frame as a clip keeps it: I420, converted here (0.1 ms at 640x480)."""
    height, width = image.shape[:2]
    if width % 2 or height % 2:
        return ClipFrame(mono, wall, (width, height), pixels=image)
    i420 = cv2.cvtColor(image, cv2.COLOR_BGR2YUV_I420)
    return ClipFrame(mono, wall, (width, height), pixels=i420)


def even(size: tuple[int, int]) -> tuple[int, int]:
    return (size[0] + size[0] % 2, size[1] + size[1] % 2)


class H264Writer:
    """Frames in, a fragmented MP4 out, written to ``file`` fragment by fragment.

    The first frame sets the clip's size (even: see the module) and range: full when it
    is a JPEG, as JPEGs are. Frames of another size or kind are converted to it. Times
    (``write``'s ``at_s``, seconds from any origin) must grow; one that does not is moved
    a tick after the last. Not thread-safe: one thread writes a clip.
    """

    def __init__(self, file: BinaryIO, fps: float, settings: EncoderSettings | None = None) -> None:
        self._file = file
        self.fps = fps if fps > 0 else 25.0
        self.settings = settings or EncoderSettings()
        self._container: av.container.OutputContainer | None = None
        self._stream: av.video.stream.VideoStream | None = None
        self._jpeg_decoder: av.VideoCodecContext | None = None
        self._format = "yuv420p"
        self._size = (0, 0)
        self._origin = 0.0
        self._last_pts = -1
        self.frames = 0
        self.first_s: float | None = None
        self.last_s = 0.0

    @property
    def length_s(self) -> float:
        """From the first frame to the last, and one frame's time after it."""
        if self.first_s is None:
            return 0.0
        return self.last_s - self.first_s + 1.0 / self.fps

    def write(self, frame: ClipFrame | Image, at_s: float) -> None:
        """One frame at ``at_s`` seconds; a picture may be a ``ClipFrame`` or BGR pixels."""
        video = self._video_frame(frame)
        if self._container is None:
            self._open(video, isinstance(frame, ClipFrame) and frame.jpeg is not None)
            self.first_s = self._origin = at_s
        stream = self._stream
        assert stream is not None
        if (video.format.name, video.width, video.height) != (self._format, *self._size):
            video = video.reformat(self._size[0], self._size[1], self._format)
        pts = max(round((at_s - self._origin) / TIME_BASE), self._last_pts + 1)
        video.pts = self._last_pts = pts
        video.time_base = TIME_BASE
        # A decoder marks each JPEG a keyframe, and x264 would make each one: none asked.
        video.pict_type = av.video.frame.PictureType.NONE
        self._mux(stream.encode(video))
        self.frames += 1
        self.last_s = at_s

    def close(self, durable: bool = True) -> None:
        """Flush the encoder and write the index (``mfra``); with ``durable``, to the disk."""
        if self._container is None:
            return
        assert self._stream is not None
        try:
            self._mux(self._stream.encode(None))
        finally:
            container, self._container = self._container, None
            container.close()
        self._file.flush()
        if durable:
            os.fsync(self._file.fileno())

    def abandon(self) -> None:
        """Stop without flushing (the disk refused): what the file holds stays."""
        container, self._container = self._container, None
        if container is not None:
            with contextlib.suppress(av.FFmpegError, OSError):
                container.close()

    def _mux(self, packets: list[av.Packet]) -> None:
        assert self._container is not None
        for packet in packets:
            self._container.mux(packet)

    def _open(self, first: av.VideoFrame, full_range: bool) -> None:
        self._size = even((first.width, first.height))
        self._format = "yuvj420p" if full_range else "yuv420p"
        container = av.open(self._file, "w", format="mp4", options={"movflags": MOVFLAGS})
        rate = Fraction(self.fps).limit_denominator(1001)
        stream = container.add_stream("libx264", rate=rate)
        stream.width, stream.height = self._size
        stream.pix_fmt = self._format
        stream.time_base = TIME_BASE
        context = stream.codec_context
        context.time_base = TIME_BASE
        context.gop_size = max(1, round(self.fps * KEYFRAME_S))
        context.options = {
            "preset": self.settings.preset,
            "crf": str(self.settings.crf),
            "threads": str(self.settings.threads),
        }
        self._container, self._stream = container, stream

    def _video_frame(self, frame: ClipFrame | Image) -> av.VideoFrame:
        if not isinstance(frame, ClipFrame):
            return self._from_bgr(frame)
        if frame.jpeg is not None:
            if self._jpeg_decoder is None:
                self._jpeg_decoder = av.CodecContext.create("mjpeg", "r")
            decoded = self._jpeg_decoder.decode(av.Packet(frame.jpeg))
            if not decoded:
                raise ValueError("a JPEG of the clip does not decode")
            return decoded[0]
        assert frame.pixels is not None
        if frame.pixels.ndim == 3:
            return self._from_bgr(frame.pixels)
        return av.VideoFrame.from_ndarray(frame.pixels, format="yuv420p")

    @staticmethod
    def _from_bgr(image: Image) -> av.VideoFrame:
        height, width = image.shape[:2]
        if width % 2 or height % 2:
            return av.VideoFrame.from_ndarray(np.ascontiguousarray(image), format="bgr24")
        i420 = cast(U8Array, cv2.cvtColor(image, cv2.COLOR_BGR2YUV_I420))
        return av.VideoFrame.from_ndarray(i420, format="yuv420p")


class BackgroundMp4:
    """An ``H264Writer`` to a file, fed from one thread and encoding in another: ``vigil
    analyze``'s ``annotated.mp4`` costs the analysis a colour conversion a frame, the
    encoding going on beside it (on a second core, where there is one). Frames wait in a
    short queue; when it is full, ``write`` waits: offline, no frame is dropped. An error
    of the encoder or the disk is raised by the next ``write`` or by ``close``."""

    QUEUE = 8

    def __init__(self, path: Path, fps: float, settings: EncoderSettings | None = None) -> None:
        self._file = path.open("wb", buffering=0)
        self._writer = H264Writer(self._file, fps, settings)
        self._queue: queue.Queue[tuple[ClipFrame, float] | None] = queue.Queue(self.QUEUE)
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="annotated-mp4", daemon=True)
        self._thread.start()

    def write(self, image: Image, at_s: float) -> None:
        if self._error is not None:
            raise self._error
        self._queue.put((decoded_clip_frame(image, at_s, at_s), at_s))

    def close(self) -> None:
        self._queue.put(None)
        self._thread.join()
        try:
            if self._error is None:
                self._writer.close()
        finally:
            self._file.close()
        if self._error is not None:
            raise self._error

    def _run(self) -> None:
        while (item := self._queue.get()) is not None:
            if self._error is not None:
                continue  # Drained, so that write() never waits on a full queue.
            try:
                self._writer.write(*item)
            except BaseException as exc:  # Raised again in the analysis' own thread.
                self._error = exc
