"""Live frames for ``WS /ws/live``: one binary message per frame and camera, made once.

A message is the frame's picture as a browser shows it, with what was found in it as
data for the page to draw (boxes, track ids, speeds, trails, the motion mask):

    4 bytes    N, the header's length, big-endian
    N bytes    the header: UTF-8 JSON
    the rest   the picture: a JPEG

A camera that sends JPEG (HTTP MJPEG, RTSP with JPEG payload, MJPG files) is passed
on in its own bytes: nothing decoded, nothing encoded for viewing. Any other camera's
picture (the demo, H.264, a device) is encoded once per frame, no wider than the
widest picture a client asked for. The camera process makes the message (only while
someone watches live) and the server hands the same bytes to every client.
"""

from __future__ import annotations

import base64
import json
import struct
from collections.abc import Mapping, Sequence

import cv2

from app.sources.frames import SourceFrame
from app.vision.detections import Detection
from app.vision.types import Mask

HEADER_LENGTH = struct.Struct(">I")
"""The 4-byte big-endian length of the header that follows it."""

MASK_PNG = [cv2.IMWRITE_PNG_BILEVEL, 1, cv2.IMWRITE_PNG_COMPRESSION, 1]
"""A binary mask as a 1-bit PNG, quickly compressed: about 0.1 ms and 200 bytes at
320x240 (a grey 8-bit one: 900 bytes)."""

Trails = Mapping[int, Sequence[tuple[float, float]]]


def live_message(
    camera_id: int,
    frame: int,
    ts: float,
    source: SourceFrame,
    detections: Sequence[Detection],
    trails: Trails | None,
    mask: Mask | None,
    width: int,
    quality: int,
) -> bytes:
    """The frame's /ws/live message; ``width``: the widest picture a client needs (0: any)."""
    header = live_header(camera_id, frame, ts, source.size, detections, trails, mask)
    return b"".join((HEADER_LENGTH.pack(len(header)), header, viewing_jpeg(source, width, quality)))


def message_camera(message: bytes) -> int | None:
    """The camera a live message is of (from its header); None for what is not one."""
    if len(message) < HEADER_LENGTH.size:
        return None
    (length,) = HEADER_LENGTH.unpack_from(message)
    try:
        header = json.loads(message[HEADER_LENGTH.size : HEADER_LENGTH.size + length])
    except ValueError:
        return None
    camera = header.get("camera_id") if isinstance(header, dict) else None
    return camera if type(camera) is int else None


def live_header(
    camera_id: int,
    frame: int,
    ts: float,
    size: tuple[int, int],
    detections: Sequence[Detection],
    trails: Trails | None,
    mask: Mask | None,
) -> bytes:
    """The header as UTF-8 JSON. Boxes and trails are in (whole) pixels of the camera's frame,
    whose ``size`` [width, height] it gives (a picture encoded smaller is scaled up to it);
    a detection without a track has ``track_id`` null and no trail."""
    trails = trails or {}
    objects = [
        {
            "box": d.box.as_list(),
            "track_id": d.track_id,
            "speed_px_s": round(d.speed_px_s, 1),
            # Whole pixels, as the annotated picture draws them: a float's text takes
            # json three times an int's, on up to 64 points a track and frame.
            "trail": [
                [int(x + 0.5), int(y + 0.5)]
                for x, y in (trails.get(d.track_id, ()) if d.track_id is not None else ())
            ],
        }
        for d in detections
    ]
    header: dict[str, object] = {
        "camera_id": camera_id,
        "frame": frame,
        "ts": round(ts, 3),
        "size": [size[0], size[1]],
        "detections": objects,
    }
    if mask is not None:
        header["mask"] = mask_png(mask)
    return json.dumps(header, separators=(",", ":")).encode()


def mask_png(mask: Mask) -> str:
    """A binary motion mask (0 / 255) in detection size as a PNG, base64."""
    ok, data = cv2.imencode(".png", mask, MASK_PNG)
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return base64.b64encode(data.tobytes()).decode("ascii")


def viewing_jpeg(source: SourceFrame, width: int, quality: int) -> bytes:
    """The camera's own JPEG where it sent one; else its picture encoded, shrunk to
    ``width`` where wider (0: as it is)."""
    if source.jpeg is not None:
        return source.jpeg
    image = source.image()
    height, full_width = image.shape[:2]
    if 0 < width < full_width:
        size = (width, max(1, round(height * width / full_width)))
        image = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    return data.tobytes()
