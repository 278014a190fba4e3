"""A frame as a live source delivers it, decoded only as far as someone needs it.

Most cameras send JPEG (HTTP MJPEG, RTSP with RTP/JPEG, MJPG files). Decoding
a 640x480 JPEG to colour costs about as much as the whole detection, and most
of the time nobody looks: a camera that is neither watched nor activated
decodes a grey frame a second (its glances at the scene); detection decodes a
grey picture at a half, quarter or eighth of the size straight from the JPEG's
DCT coefficients (libjpeg's scaled decoding, several times cheaper); only a
viewer or a snapshot decodes full colour, once per frame. A frame that arrives
already decoded (demo scene, H.264 stream, a device) offers the same interface.

Both decoders are libjpeg-turbo, pixel for pixel alike. Grey goes through
OpenCV, whose scaled decoding is as fast as any; colour through simplejpeg
(TurboJPEG's own colour conversion), which took 0.75 ms where OpenCV's
``imdecode`` took 1.14 at 640x480, and 4.4 where it took 6.0 at 1920x1080
(best of 15 here). A JPEG that libjpeg warns about (damaged data, a cut-off
frame, an odd header) is left to OpenCV, which decides as for the grey: what
it decodes (as far as it goes), or a frame error.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import cast

import cv2
import numpy as np
import simplejpeg

from app.vision.preprocess import to_gray
from app.vision.types import GrayImage, Image

REDUCED_GRAY = {
    8: cv2.IMREAD_REDUCED_GRAYSCALE_8,
    4: cv2.IMREAD_REDUCED_GRAYSCALE_4,
    2: cv2.IMREAD_REDUCED_GRAYSCALE_2,
}
"""Scaled-decode flags, largest reduction first."""

SOF_MARKERS = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
"""JPEG start-of-frame markers (every coding process); C4, C8 and CC are not frames."""

MAX_SIDE = 16384
"""Larger than any camera's picture; a header claiming more is garbage, not a frame."""


class FrameError(ValueError):
    """One frame that cannot be decoded (a camera sending garbage); the next may be fine."""


class SourceFrame(ABC):
    """One frame: its size, and its pixels in the form asked for."""

    size: tuple[int, int]
    """(width, height) of the full picture."""
    jpeg: bytes | None = None
    """The source's own JPEG, when it sent one: served as is when nothing is drawn on it."""

    @abstractmethod
    def image(self) -> Image:
        """The full-size colour picture (decoded once, then kept)."""

    @abstractmethod
    def gray(self, min_width: int) -> GrayImage:
        """A grey picture at least ``min_width`` wide (or full size), as cheaply as possible."""


class DecodedFrame(SourceFrame):
    def __init__(self, image: Image) -> None:
        self._image = image
        self.size = (image.shape[1], image.shape[0])

    def image(self) -> Image:
        return self._image

    def gray(self, min_width: int) -> GrayImage:
        return to_gray(self._image)


class JpegFrame(SourceFrame):
    """A JPEG as the camera sent it. Raises FrameError when it is not a readable JPEG.

    Two threads (the worker, a viewer's encoder) may ask for the same pixels at
    once; each then decodes, and either result is kept: the same picture.
    """

    def __init__(self, data: bytes) -> None:
        self.jpeg = data
        self.size = jpeg_size(data)
        self._image: Image | None = None
        self._gray: tuple[int, GrayImage] | None = None

    def image(self) -> Image:
        if self._image is None:
            assert self.jpeg is not None
            try:
                # Strict: on any warning of libjpeg's, OpenCV's answer, as the grey's.
                picture = simplejpeg.decode_jpeg(self.jpeg, colorspace="BGR", strict=True)
            except ValueError:
                picture = self._decode(cv2.IMREAD_COLOR)
            self._image = cast(Image, picture)
        return self._image

    def gray(self, min_width: int) -> GrayImage:
        if self._image is not None:
            return to_gray(self._image)
        if self._gray is None or self._gray[0] != min_width:
            width = self.size[0]
            reduction = next((r for r in REDUCED_GRAY if width // r >= min_width > 0), 1)
            flag = REDUCED_GRAY.get(reduction, cv2.IMREAD_GRAYSCALE)
            self._gray = (min_width, self._decode(flag))
        return self._gray[1]

    def _decode(self, flag: int) -> np.ndarray:
        """Through OpenCV (``flag``)."""
        assert self.jpeg is not None
        # As its header says (``size``): an EXIF orientation would turn the picture, not
        # the header, and boxes found on one would be drawn on the other.
        flag |= cv2.IMREAD_IGNORE_ORIENTATION
        picture = cv2.imdecode(np.frombuffer(self.jpeg, np.uint8), flag)
        if picture is None:
            raise FrameError("camera sent a JPEG that does not decode")
        return picture


def jpeg_size(data: bytes) -> tuple[int, int]:
    """(width, height) from a JPEG's start-of-frame header, without decoding it."""
    if data[:2] != b"\xff\xd8":
        raise FrameError("camera sent something that is not a JPEG")
    at = 2
    while at + 4 <= len(data):
        if data[at] != 0xFF:
            raise FrameError("camera sent a corrupt JPEG header")
        marker = data[at + 1]
        if marker == 0xFF:  # Fill byte before a marker.
            at += 1
            continue
        length = int.from_bytes(data[at + 2 : at + 4], "big")
        if marker in SOF_MARKERS and at + 9 <= len(data):
            height = int.from_bytes(data[at + 5 : at + 7], "big")
            width = int.from_bytes(data[at + 7 : at + 9], "big")
            if not (0 < width <= MAX_SIDE and 0 < height <= MAX_SIDE):
                raise FrameError(f"camera sent a JPEG claiming {width}x{height} pixels")
            return width, height
        if marker == 0xDA or length < 2:  # Image data before any frame header.
            break
        at += 2 + length
    raise FrameError("camera sent a JPEG without a frame header")
