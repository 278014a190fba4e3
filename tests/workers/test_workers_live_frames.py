"""Live frames in a camera process: one /ws/live message per frame, made once, only while
watched; the camera's own JPEG passed on as it came; the annotated picture untouched."""

from __future__ import annotations

import base64
import json
import struct
import threading
from pathlib import Path
from typing import Any, cast

import cv2
import numpy as np

from app.sources.frames import DecodedFrame, JpegFrame
from app.vision.detections import Box, Detection
from app.workers.camera_host import _FrameSender, _Link
from app.workers.hub import LiveFrame
from app.workers.live_frames import live_message
from tests.api.vigil_livekit import frame_at, wait_for, write_video
from tests.workers.conftest import make_worker


def parse(message: bytes) -> tuple[dict[str, Any], bytes]:
    (length,) = struct.unpack(">I", message[:4])
    return json.loads(message[4 : 4 + length]), message[4 + length :]


def test_a_message_is_a_length_a_json_header_and_the_cameras_own_jpeg() -> None:
    jpeg = cv2.imencode(".jpg", frame_at(10))[1].tobytes()
    tracked = Detection(Box(30, 90, 40, 40), (50.0, 110.0), 1600.0, track_id=7, speed_px_s=90.04)
    untracked = Detection(Box(200, 10, 10, 10), (205.0, 15.0), 100.0)
    mask = np.zeros((120, 160), np.uint8)
    mask[45:65, 15:35] = 255
    trails = {7: [(40.0, 110.0), (44.25, 110.0), (50.0, 110.0)], 8: [(1.0, 1.0), (2.0, 2.0)]}
    message = live_message(
        3, 12, 1700000000.12345, JpegFrame(jpeg), [tracked, untracked], trails, mask, 160, 80
    )
    header, picture = parse(message)
    assert picture == jpeg  # Untouched, whatever the width asked for.
    assert header == {
        "camera_id": 3,
        "frame": 12,
        "ts": 1700000000.123,
        "size": [320, 240],
        "detections": [
            {
                "box": [30, 90, 40, 40],
                "track_id": 7,
                "speed_px_s": 90.0,
                "trail": [[40.0, 110.0], [44.2, 110.0], [50.0, 110.0]],
            },
            {"box": [200, 10, 10, 10], "track_id": None, "speed_px_s": 0.0, "trail": []},
        ],
        "mask": header["mask"],
    }
    png = base64.b64decode(header["mask"])
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert np.array_equal(cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED), mask)


def test_a_decoded_frame_is_encoded_no_wider_than_asked() -> None:
    image = frame_at(10)
    for width, shape in ((160, (120, 160, 3)), (0, (240, 320, 3)), (640, (240, 320, 3))):
        header, picture = parse(
            live_message(1, 1, 0.0, DecodedFrame(image), [], None, None, width, 80)
        )
        assert cv2.imdecode(np.frombuffer(picture, np.uint8), cv2.IMREAD_COLOR).shape == shape
        assert header["size"] == [320, 240] and "mask" not in header


def test_a_frames_message_is_made_once_and_then_is_made_already() -> None:
    jpeg = cv2.imencode(".jpg", frame_at(3))[1].tobytes()
    item = LiveFrame(5, 1.0, JpegFrame(jpeg))
    assert item.made("live") is None
    message = item.live(2, 320)
    assert item.made("live") is message and item.live(2, 320) is message
    assert item.made("picture") == jpeg  # The MJPEG viewers' picture: still its own.


class _Pipe:
    def __init__(self) -> None:
        self.sent: list[tuple[Any, ...]] = []
        self.lock = threading.Lock()

    def send(self, item: tuple[Any, ...]) -> None:
        with self.lock:
            self.sent.append(item)


def test_the_camera_process_sends_live_messages_only_while_watched_live(
    parts: dict[str, Any], tmp_path: Path
) -> None:
    worker = make_worker(parts, str(write_video(tmp_path / "v.avi")))
    pipe = _Pipe()
    sender = _FrameSender(cast(_Link, pipe))
    sender.start(worker.camera_id, 1)
    worker.hub.on_publish = lambda item: sender.offer(worker.camera_id, item)
    worker.start()
    try:
        wait_for(lambda: worker.frames >= 10, 10, "frames")
        assert pipe.sent == []  # Nobody watches: nothing is made or sent.
        sender.watch(worker.camera_id, 1, {"picture": 0, "histogram": 0, "live": 1}, 320)
        wait_for(lambda: len(pipe.sent) >= 5, 10, "live frames")
        for kind, camera_id, generation, picture, histogram, live in pipe.sent[:5]:
            assert (kind, camera_id, generation) == ("frame", worker.camera_id, 1)
            assert picture is None and histogram is None  # No MJPEG viewer: not drawn.
            header, jpeg = parse(live)
            assert header["camera_id"] == worker.camera_id and jpeg[:2] == b"\xff\xd8"
        assert worker.encodes.frames == 0
        sender.watch(worker.camera_id, 1, {"picture": 0, "histogram": 0, "live": 0}, 0)
        count = len(pipe.sent)
        wait_for(lambda: worker.frames >= 40, 10, "more frames")
        assert len(pipe.sent) <= count + 1  # One may have been under way.
    finally:
        worker.request_stop()
        worker.join(5)
        sender.stop()
