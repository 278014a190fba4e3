"""Frames from a recorded video file or a folder of images (offline mode).

The header's frame count is never trusted (some AVIs claim 444 frames and
hold 68): frames are decoded until the reader stops. A frame that does not
decode (a damaged JPEG in an MJPEG AVI, a corrupt image in a folder) is
skipped and keeps its place: the frames after it keep their decode index,
so their times stay right. A video is read until MAX_BAD_RUN frames in a row
fail, which is also how its end looks to the reader.
"""

from __future__ import annotations

import math
import re
from collections.abc import Generator, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import cv2

from app.sources.read_ahead import read_ahead
from app.vision.types import Image

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".webp")
DEFAULT_FPS = 25.0
"""The rate assumed for a folder of frames, or a video whose header gives none that is sane."""
MAX_FPS = 1000.0
MIN_FRAMES = 2
"""Motion needs two frames: a still picture (a PNG named .avi) is not a video to analyse."""
MAX_BAD_RUN = 100
"""Frames in a row that may fail to decode before a video is taken to end there (its end
looks the same to the reader, and reading past it costs microseconds a frame)."""
HEADER_SLACK = 0.01
"""A video read this much short of its header's frame count (at least one frame) is not
reported as cut short: some containers' counts are estimates from the duration."""
SINGLE_PICTURE = (
    "{path} holds only one decodable frame (a picture, not a video?): motion needs at least two"
)
CDNET_MARKERS = ("groundtruth", "temporalROI.txt")
"""Beside these a folder is a CDnet sequence, read from its ``input/`` (its ROI pictures
are not frames)."""
FFMPEG_LOG_QUIET = "-8"
"""``OPENCV_FFMPEG_LOGLEVEL`` for none of FFmpeg's own messages (AV_LOG_QUIET)."""
_NUMBER = re.compile(r"(\d+)\D*$")
_DIGITS = re.compile(r"(\d+)")


def frame_number(path: Path) -> int | None:
    """The number a frame file's name ends in (CDnet in000950.jpg -> 950), if any."""
    match = _NUMBER.search(path.stem)
    return int(match.group(1)) if match else None


def valid_fps(rate: float) -> bool:
    """A frame rate Vigil works with: a number in (0, MAX_FPS]."""
    return math.isfinite(rate) and 0 < rate <= MAX_FPS


def frame_rate(capture: cv2.VideoCapture) -> float:
    """The capture's frame rate, or DEFAULT_FPS when the header's is missing or absurd."""
    rate = capture.get(cv2.CAP_PROP_FPS)
    return float(rate) if valid_fps(rate) else DEFAULT_FPS


class InputError(ValueError):
    """The input cannot be analysed; the message is one readable line."""


def check_frame_size(width: int, height: int, max_pixels: int | None) -> None:
    """Refuse frames too large to analyse (a hostile header can claim any size)."""
    if width <= 0 or height <= 0:
        raise InputError(f"the video claims frames of {width}x{height} pixels")
    if max_pixels is not None and width * height > max_pixels:
        raise InputError(
            f"frames of {width}x{height} are too large: at most {max_pixels:,} pixels are allowed"
        )


@dataclass
class VideoInput:
    """An opened input: its frames (decoded lazily), rate, size and frame names."""

    path: Path
    fps: float
    size: tuple[int, int]
    images: list[Path] | None = None
    """Sorted frame files, for a folder input."""
    header_frames: int | None = None
    """What the container claims; informational only."""
    skipped: list[int] = field(default_factory=list)
    """Decode indices of the frames that did not decode and were skipped (filled as
    ``indexed_frames`` reads)."""
    frames_read: int = 0
    """Decode indices read so far: the index after the last frame read (decoded or skipped)."""

    @property
    def expected_frames(self) -> int | None:
        """How many frames to expect, for progress only (a video's header may lie)."""
        return len(self.images) if self.images is not None else self.header_frames

    @property
    def frame_numbers(self) -> list[int | None] | None:
        """Numbers in the frame files' names (CDnet in000950.jpg -> 950), for truth matching."""
        return [frame_number(p) for p in self.images] if self.images is not None else None

    @property
    def ended_early(self) -> bool:
        """Whether reading stopped well short of the frames the video's header claims."""
        if self.images is not None or not self.header_frames:
            return False
        return self.header_frames - self.frames_read > max(1, self.header_frames * HEADER_SLACK)

    def frames(self, ahead: int = 0) -> Generator[Image]:
        """The frames that decode, in order (``close`` it to stop reading early);
        ``ahead``: decoded up to that many frames ahead by a thread (``read_ahead``)."""
        for _, frame in self.indexed_frames(ahead):
            yield frame

    def indexed_frames(self, ahead: int = 0) -> Iterator[tuple[int, Image]]:
        """(decode index, frame) for every frame that decodes; the ones that do not are
        skipped, keep their index and are listed in ``skipped``. ``ahead``: as for
        ``frames``."""
        self.skipped, self.frames_read = [], 0
        failed: list[int] = []
        decoded = self._images() if self.images is not None else self._video()
        for index, frame in read_ahead(decoded, ahead) if ahead else decoded:
            if frame is None:
                failed.append(index)
                continue
            self.skipped += failed  # Frames after them decoded: they were damaged, not the end.
            failed = []
            self.frames_read = index + 1
            yield index, frame
        if self.images is not None:  # Each image is a frame, the last ones too.
            self.skipped += failed
            self.frames_read = len(self.images)

    def _images(self) -> Iterator[tuple[int, Image | None]]:
        assert self.images is not None
        for index, image_path in enumerate(self.images):
            frame = cv2.imread(str(image_path), cv2.IMREAD_COLOR)
            if frame is not None and (frame.shape[1], frame.shape[0]) != self.size:
                raise InputError(
                    f"{image_path.name} is {frame.shape[1]}x{frame.shape[0]}, "
                    f"the first frame was {self.size[0]}x{self.size[1]}"
                )
            yield index, frame

    def _video(self) -> Iterator[tuple[int, Image | None]]:
        capture = cv2.VideoCapture(str(self.path), cv2.CAP_FFMPEG)
        try:
            index = bad_run = 0
            while bad_run < MAX_BAD_RUN:
                ok, frame = capture.read()
                if not ok or frame is None:
                    bad_run += 1
                    yield index, None
                else:
                    # A stream can switch to other (larger) frames mid-way; every later stage
                    # and the annotated video assume the first frame's size.
                    if (frame.shape[1], frame.shape[0]) != self.size:
                        raise InputError(
                            f"frame {index} is {frame.shape[1]}x{frame.shape[0]}, "
                            f"the first frame was {self.size[0]}x{self.size[1]}"
                        )
                    bad_run = 0
                    yield index, frame
                index += 1
        finally:
            capture.release()


def check_fps(fps: float | None) -> None:
    """Refuse a frame rate that is not a number in (0, MAX_FPS]."""
    if fps is not None and not valid_fps(fps):
        raise InputError(f"the frame rate must be more than 0 and at most {MAX_FPS:g}, not {fps}")


def _read_good(capture: cv2.VideoCapture) -> Image | None:
    """The next frame that decodes, skipping at most MAX_BAD_RUN that do not."""
    for _ in range(MAX_BAD_RUN):
        ok, frame = capture.read()
        if ok and frame is not None:
            return frame
    return None


def _grab_good(capture: cv2.VideoCapture) -> bool:
    """Whether another frame decodes, skipping at most MAX_BAD_RUN that do not."""
    return any(capture.grab() for _ in range(MAX_BAD_RUN))


def open_input(path: Path, fps: float | None = None, max_pixels: int | None = None) -> VideoInput:
    """Open a video file or a folder of frames, or raise InputError with the reason.

    ``max_pixels`` caps width x height, checked against the header before a frame
    is decoded and again against the first decoded frame.
    """
    check_fps(fps)
    if not path.exists():
        raise InputError(f"input not found: {path}")
    if path.is_dir():
        return _open_folder(path, fps, max_pixels)
    if not path.is_file():
        raise InputError(f"input is not a file or folder: {path}")
    try:
        with path.open("rb") as handle:
            if not handle.read(1):
                raise InputError(f"input is empty: {path}")
    except PermissionError:
        raise InputError(f"input is not readable: {path}") from None
    capture = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
    try:
        if not capture.isOpened():
            raise InputError(f"not a video FFmpeg can decode: {path}")
        header_size = (
            capture.get(cv2.CAP_PROP_FRAME_WIDTH),
            capture.get(cv2.CAP_PROP_FRAME_HEIGHT),
        )
        if all(math.isfinite(v) and v > 0 for v in header_size):
            check_frame_size(int(header_size[0]), int(header_size[1]), max_pixels)
        first = _read_good(capture)
        if first is None:
            raise InputError(f"video has no decodable frames: {path}")
        check_frame_size(first.shape[1], first.shape[0], max_pixels)
        if not _grab_good(capture):
            raise InputError(SINGLE_PICTURE.format(path=path))
        rate = fps or frame_rate(capture)
        claimed = capture.get(cv2.CAP_PROP_FRAME_COUNT)
    finally:
        capture.release()
    return VideoInput(
        path,
        rate,
        (first.shape[1], first.shape[0]),
        # The header's count is informational and may be anything, NaN included.
        header_frames=int(claimed) if math.isfinite(claimed) and claimed > 0 else None,
    )


def list_images(folder: Path) -> list[Path]:
    """The folder's image files, sorted by name, numbers in names by their value
    (2.png before 10.png, as in000002.jpg before in000010.jpg)."""
    try:
        images = [p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES]
    except PermissionError:
        raise InputError(f"folder is not readable: {folder}") from None
    return sorted(images, key=_natural_order)


def _natural_order(path: Path) -> list[str | int]:
    # Text and numbers alternate, text first (maybe empty), so like parts are compared.
    return [int(part) if index % 2 else part for index, part in enumerate(_DIGITS.split(path.name))]


def _open_folder(folder: Path, fps: float | None, max_pixels: int | None) -> VideoInput:
    images = list_images(folder)
    sequence = folder / "input"
    if sequence.is_dir() and (
        len(images) < MIN_FRAMES or any((folder / name).exists() for name in CDNET_MARKERS)
    ):
        # A data set's sequence (CDnet; Wallflower, whose folder holds one label picture):
        # its frames, not its ROI or label pictures.
        folder, images = sequence, list_images(sequence)
    if not images:
        raise InputError(f"no image frames in folder: {folder}")
    if len(images) < MIN_FRAMES:
        raise InputError(f"{folder} holds only one image: motion needs at least two frames")
    # The first picture that decodes sets the size; one that does not is a skipped frame,
    # but there must be a second that decodes.
    decoded = (f for f in (cv2.imread(str(p), cv2.IMREAD_COLOR) for p in images) if f is not None)
    first = next(decoded, None)
    if first is None:
        raise InputError(f"none of the {len(images)} images in {folder} decodes")
    if next(decoded, None) is None:
        raise InputError(
            f"only one of the {len(images)} images in {folder} decodes: motion needs at least two"
        )
    check_frame_size(first.shape[1], first.shape[0], max_pixels)
    return VideoInput(
        folder, float(fps or DEFAULT_FPS), (first.shape[1], first.shape[0]), images=images
    )
