"""Live frames in a camera process: one /ws/live message per frame, made once, only while
watched; the camera's own JPEG passed on as it came; the annotated picture untouched."""

from __future__ import annotations

import base64
import json
import multiprocessing
import struct
import threading
import time
from pathlib import Path
from typing import Any, cast

import cv2
import numpy as np

from app.sources.frames import DecodedFrame, JpegFrame
from app.vision.detections import Box, Detection
from app.workers.frame_sender import FrameSender, Link
from app.workers.hub import LiveFrame
from app.workers.live_frames import live_message
from app.workers.live_pipe import LivePipeReader, LivePipeWriter
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
                "trail": [[40, 110], [44, 110], [50, 110]],
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
    """A JPEG camera's live messages go over the live pipe, written by the camera's own
    thread; the main pipe carries nothing while no MJPEG viewer or histogram watches."""
    worker = make_worker(parts, str(write_video(tmp_path / "v.avi")))
    reading, writing = multiprocessing.Pipe(duplex=False)
    received: list[tuple[int, int, bytes]] = []
    reader = LivePipeReader(reading, lambda *message: received.append(message), None)
    pipe = _Pipe()
    sender = FrameSender(cast(Link, pipe), LivePipeWriter(writing))
    sender.start(worker.camera_id, 7)
    worker.hub.on_publish = lambda item: sender.offer(worker.camera_id, item)
    worker.start()
    try:
        wait_for(lambda: worker.frames >= 10, 10, "frames")
        assert received == []  # Nobody watches: nothing is made or sent.
        sender.watch(worker.camera_id, 7, {"picture": 0, "histogram": 0, "live": 1}, 320)
        wait_for(lambda: len(received) >= 5, 10, "live frames")
        for camera_id, generation, message in received[:5]:
            assert (camera_id, generation) == (worker.camera_id, 7)
            header, jpeg = parse(message)
            assert header["camera_id"] == worker.camera_id and jpeg[:2] == b"\xff\xd8"
        assert pipe.sent == [] and worker.encodes.frames == 0  # No MJPEG viewer: not drawn.
        sender.watch(worker.camera_id, 7, {"picture": 1, "histogram": 0, "live": 1}, 320)
        wait_for(lambda: len(pipe.sent) >= 3, 10, "MJPEG pictures too")
        kind, camera_id, generation, picture, histogram = pipe.sent[-1]
        assert (kind, camera_id, generation, histogram) == ("frame", worker.camera_id, 7, None)
        assert picture[:2] == b"\xff\xd8"
        sender.watch(worker.camera_id, 7, {"picture": 0, "histogram": 0, "live": 0}, 0)
        count = len(received)
        wait_for(lambda: worker.frames >= 60, 10, "more frames")
        assert len(received) <= count + 1  # One may have been under way.
    finally:
        worker.request_stop()
        worker.join(5)
        sender.stop()
        writing.close()
        reader.close()


def test_a_full_live_pipe_drops_frames_and_never_blocks() -> None:
    reading, writing = multiprocessing.Pipe(duplex=False)
    writer = LivePipeWriter(writing)
    message = b"x" * 100_000
    started = time.monotonic()
    written = sum(writer.write(1, 1, message) for _ in range(40))  # Nobody reads.
    assert time.monotonic() - started < 1.0
    assert 0 < written < 40 and writer.dropped == 40 - written
    received: list[bytes] = []
    reader = LivePipeReader(reading, lambda _c, _g, m: received.append(m), None)
    wait_for(lambda: len(received) == written, 5, "what fitted")
    assert all(m == message for m in received)  # Whole messages, none cut.
    writer.close()
    reader.close()
