"""The server's face of a camera in a camera process (``RemoteCamera``), before it reports;
what the server and a camera process tell /ws about a process that died."""

from __future__ import annotations

import pickle
from types import SimpleNamespace
from typing import Any, cast

import cv2

from app.events.messages import CameraStatus, MotionEnd, WsMessage, parse_message
from app.recording.mp4 import ClipFrame, H264Writer
from app.storage import ClipStore
from app.vision.motion import DEFAULT_METHOD
from app.workers.bus import EventBus
from app.workers.camera_host import (
    CameraProcess,
    RemoteCamera,
    _end_events,
    _WorkerLink,
)
from app.workers.frame_sender import Link
from tests.api.vigil_livekit import FPS, frame_at
from tests.workers.conftest import make_worker

JPEG = cv2.imencode(".jpg", frame_at(10))[1].tobytes()


def test_a_camera_shows_a_new_workers_status_until_its_process_reports(
    parts: dict[str, Any],
) -> None:
    """Until its process reports, ``RemoteCamera`` shows a new ``CameraWorker``'s status:
    same keys, same values, so the API and /ws show a camera alike before and after."""
    worker = make_worker(parts, "demo")  # Never started: as a new worker reports.
    process = CameraProcess(3, parts["settings"], parts["bus"])  # Never started either.
    remote = RemoteCamera({"id": worker.camera_id, "active": 0}, process)
    shown = remote.status()
    assert shown.pop("process") == 3
    assert shown == worker.status()


class _Recorder(EventBus):
    """A bus that keeps what it is given, in its wire form."""

    def __init__(self) -> None:
        super().__init__()
        self.sent: list[dict[str, Any]] = []

    def publish(self, message: WsMessage | dict[str, Any]) -> None:
        self.sent.append(message.wire() if isinstance(message, WsMessage) else message)


def test_a_dead_processs_cameras_are_told_down_as_camera_status(parts: dict[str, Any]) -> None:
    bus = _Recorder()
    process = CameraProcess(2, parts["settings"], bus)
    process.cameras[9] = RemoteCamera({"id": 9, "active": 1}, process)
    process._stopping.set()  # Told, not started again.
    process._restart("died (signal 9, SIGKILL)")
    (down,) = bus.sent
    assert isinstance(parse_message(down), CameraStatus) and parse_message(down).wire() == down
    assert down["type"] == "status" and down["state"] == "error" and down["process"] == 2
    assert down["reason"] == "camera process died (signal 9, SIGKILL)" and down["active"]


def test_events_a_dead_process_left_open_end_with_a_motion_end_over_the_pipe(
    parts: dict[str, Any],
) -> None:
    """What crosses the pipe is the message's wire form: a plain dict, cheap to pickle."""
    db = parts["db"]
    camera_id = db.add_camera("cam", "demo", DEFAULT_METHOD, 100.0)
    event_id = db.add_event(camera_id, 1000.0, [[1, 2, 3, 4]], 12.0, [1])
    sent: list[tuple[Any, ...]] = []
    link = _WorkerLink(cast(Link, SimpleNamespace(send=sent.append)), 5)
    _end_events(db, link, camera_id)
    ((kind, generation, wire),) = sent
    assert (kind, generation) == ("message", 5) and type(wire) is dict
    assert pickle.loads(pickle.dumps(wire)) == wire
    assert isinstance(parse_message(wire), MotionEnd) and parse_message(wire).wire() == wire
    assert (wire["camera_id"], wire["event_id"], wire["ts"]) == (camera_id, event_id, 1000.0)


def test_a_clip_a_dead_process_was_recording_is_finished_and_named_in_its_motion_end(
    parts: dict[str, Any],
) -> None:
    db = parts["db"]
    clips = ClipStore(parts["settings"].clips_dir)
    camera_id = db.add_camera("cam", "demo", DEFAULT_METHOD, 100.0)
    event_id = db.add_event(camera_id, 1000.0, [[1, 2, 3, 4]], 12.0, [1])
    relative, path = clips.create(camera_id, 1000.0, event_id)
    db.start_clip(event_id, relative, 997.0)
    with path.open("wb", buffering=0) as file:  # Two seconds written, then the kill.
        writer = H264Writer(file, FPS)
        for i in range(int(2 * FPS) + 3):
            writer.write(ClipFrame(i / FPS, 0.0, (320, 240), jpeg=JPEG), i / FPS)
    sent: list[tuple[Any, ...]] = []
    link = _WorkerLink(cast(Link, SimpleNamespace(send=sent.append)), 5)
    _end_events(db, link, camera_id, clips)
    ((_, _, wire),) = sent
    assert wire["clip"] == f"/api/events/{event_id}/clip.mp4"
    assert 1.0 <= wire["clip_s"] <= 2.2
    assert wire["clip_s"] == db.event(event_id)["clip_s"]  # type: ignore[index]
