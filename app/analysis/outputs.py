"""Writers for the files `vigil analyze` leaves in its output folder."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import IO, Any

import cv2

from app.core.atomic import write_atomic
from app.recording.mp4 import BackgroundMp4
from app.vision.detections import Detection
from app.vision.types import Image

TRACKS_HEADER = (
    "frame",
    "time_s",
    "track_id",
    "x",
    "y",
    "w",
    "h",
    "cx",
    "cy",
    "area",
    "distance_px",
    "speed_px_s",
)


class TracksCsv:
    """tracks.csv: one row per detected object per frame."""

    def __init__(self, path: Path) -> None:
        self._file: IO[str] = path.open("w", newline="")
        self._writer = csv.writer(self._file)
        self._writer.writerow(TRACKS_HEADER)

    def write(self, frame: int, time_s: float, detections: list[Detection]) -> None:
        for d in detections:
            self._writer.writerow(
                (
                    frame,
                    f"{time_s:.4f}",
                    d.track_id,
                    d.box.x,
                    d.box.y,
                    d.box.w,
                    d.box.h,
                    f"{d.centroid[0]:.2f}",
                    f"{d.centroid[1]:.2f}",
                    f"{d.area:.1f}",
                    f"{d.distance_px:.3f}",
                    f"{d.speed_px_s:.3f}",
                )
            )

    def close(self) -> None:
        self._file.close()


class AnnotatedVideo:
    """annotated.avi, Motion-JPEG: every OpenCV build writes it and every player reads it;
    and, given ``mp4``, annotated.mp4 with the same frames in H.264, which a browser plays.

    Frame for frame with the input: frame N of the video is decode index N, and a frame
    of the input that did not decode is the previous annotated frame again. Its frames
    are the input's size: FFmpeg's MJPEG encoder (4:2:0) would drop the last column and
    row of an odd-sized frame, so those are written by OpenCV's own MJPEG writer, and
    so is every frame where OpenCV was built without FFmpeg. (H.264 needs even sides:
    annotated.mp4 of an odd-sized video is a pixel larger.)
    """

    def __init__(
        self, path: Path, fps: float, size: tuple[int, int], mp4: Path | None = None
    ) -> None:
        fourcc = cv2.VideoWriter.fourcc(*"MJPG")
        odd = size[0] % 2 or size[1] % 2
        # FFmpeg's files are smaller at the same quality; OpenCV's writer is always built.
        backends = [cv2.CAP_OPENCV_MJPEG] if odd else [cv2.CAP_FFMPEG, cv2.CAP_OPENCV_MJPEG]
        for backend in backends:
            self._writer = cv2.VideoWriter(str(path), backend, fourcc, fps, size)
            if self._writer.isOpened():
                break
        else:
            raise OSError(f"cannot write video {path}")
        self.fps = fps
        self._mp4 = BackgroundMp4(mp4, fps) if mp4 is not None else None
        self._written = 0
        self._last: Image | None = None

    def write(self, frame: Image, index: int | None = None) -> None:
        """Write ``frame`` as decode index ``index`` (default: the next one)."""
        if index is not None:
            self._repeat_until(index, frame)
        self._put(frame)
        self._last = frame

    def _put(self, frame: Image) -> None:
        self._writer.write(frame)
        if self._mp4 is not None:
            self._mp4.write(frame, self._written / self.fps)
        self._written += 1

    def pad_to(self, frames: int) -> None:
        """Repeat the last frame until the video holds ``frames`` frames."""
        if self._last is not None:
            self._repeat_until(frames, self._last)

    def _repeat_until(self, frames: int, first: Image) -> None:
        # Before any frame was written (the input's first frames did not decode), the
        # first one that did stands in for them.
        filler = self._last if self._last is not None else first
        while self._written < frames:
            self._put(filler)

    def close(self) -> None:
        self._writer.release()
        if self._mp4 is not None:
            self._mp4.close()


def write_json(path: Path, data: Any) -> None:
    """Write JSON atomically: a reader never sees half a file."""
    write_atomic(path, json.dumps(data, indent=2, allow_nan=False).encode())


def write_image(path: Path, image: Image, quality: int = 90) -> None:
    suffix = path.suffix.lower()
    params = [cv2.IMWRITE_JPEG_QUALITY, quality] if suffix in (".jpg", ".jpeg") else []
    ok, encoded = cv2.imencode(suffix, image, params)
    if not ok:
        raise OSError(f"cannot encode {path.name}")
    write_atomic(path, encoded.tobytes())
