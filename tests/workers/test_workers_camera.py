"""A camera worker on real sources: detection only when active, lazy JPEGs, alarms, reconnects."""

from __future__ import annotations

import asyncio
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.sources.frames import DecodedFrame
from app.sources.synthetic import MovingObject, Scene
from app.storage import Database
from app.workers.camera import DETECTION_WARMING, PLAIN_SLEEP_S, PREPARING, CameraWorker
from app.workers.hub import viewer_jpeg
from tests.api.vigil_livekit import FPS, MjpegCamera, wait_for, write_video
from tests.conftest import lamplight, lit, write_scene_video
from tests.workers.conftest import make_worker, worker_parts


def _messages_until_motion_end(parts: dict[str, Any], worker: CameraWorker) -> list[dict[str, Any]]:
    """Activate the camera and collect the bus's messages until the first event ends."""
    received: list[dict[str, Any]] = []

    async def listen() -> None:
        queue = parts["bus"].subscribe()
        worker.set_active(True)
        while True:
            message = await asyncio.wait_for(queue.get(), 15)
            assert message is not None
            received.append(message)
            if message["type"] == "motion_end":
                return

    worker.start()
    try:
        asyncio.run(listen())
    finally:
        worker.request_stop()
        worker.join(5)
    return received


def test_frames_are_encoded_only_when_watched_and_once(
    parts: dict[str, Any], tmp_path: Path
) -> None:
    worker = make_worker(parts, str(write_video(tmp_path / "v.avi")))
    worker.start()
    try:
        wait_for(lambda: worker.frames >= 20, 10, "frames")
        assert worker.encodes.frames == 0 and worker.encodes.histograms == 0
        assert worker.processed == 0, "no detection before Activate"
        latest = worker.hub.latest
        assert latest is not None
        # Nothing to draw: viewers get the camera's own JPEG, neither decoded nor encoded,
        # and made already (a viewer's loop takes it at once, with no worker thread).
        assert latest.source.jpeg is not None and latest.made("picture") == latest.source.jpeg
        assert asyncio.run(viewer_jpeg(latest, "picture")) == latest.source.jpeg
        assert latest.made("histogram") is None
        histogram = asyncio.run(viewer_jpeg(latest, "histogram"))
        assert histogram[:2] == b"\xff\xd8" and latest.made("histogram") == histogram
        assert (worker.encodes.frames, worker.encodes.histograms) == (0, 1)
        assert worker.state == "live" and 10 < worker.fps < 20, worker.fps
        worker.set_active(True)
        boxed = wait_for(
            lambda: (item := worker.hub.latest) is not None and item.detections and item,
            10,
            "a frame with boxes",
        )
        assert boxed.made("picture") is None, "boxes to draw: nothing is made yet"
        assert asyncio.run(viewer_jpeg(boxed, "picture")) is boxed.jpeg()  # One encode.
        assert worker.encodes.frames == 1 and boxed.jpeg() != boxed.source.jpeg
        assert boxed.made("picture") is boxed.jpeg()
    finally:
        worker.request_stop()
        assert worker.join(5)
    assert worker.state == "stopped"


def test_alarm_writes_event_and_snapshots(parts: dict[str, Any], tmp_path: Path) -> None:
    worker = make_worker(parts, str(write_video(tmp_path / "v.avi")))
    received = _messages_until_motion_end(parts, worker)
    (alarm,) = [m for m in received if m["type"] == "alarm"]
    db: Database = parts["db"]
    # The video loops: a worker that fell behind may start the next crossing's event
    # before it sees the stop. This test is about the first.
    (event,) = [e for e in db.events() if e["id"] == alarm["event_id"]]
    assert event["ended_at"] is not None
    assert event["max_area"] > 1000
    snaps = [s for s in db.snapshots() if s["event_id"] == event["id"]]
    assert {s["kind"] for s in snaps} == {"frame", "difference"}
    for snap in snaps:
        path = parts["snapshots"].path(snap["path"])
        assert path.read_bytes()[:2] == b"\xff\xd8" and path.stat().st_size == snap["size"]
    assert not list(parts["settings"].snapshots_dir.rglob(".tmp-*"))


def test_lost_camera_reconnects(parts: dict[str, Any]) -> None:
    camera = MjpegCamera().start()
    worker = make_worker(parts, camera.url)
    states: list[str] = []
    worker.start()
    try:
        wait_for(lambda: worker.state == "live" and worker.frames > 5, 15, "live")
        camera.stop()
        wait_for(lambda: worker.state == "reconnecting", 10, "reconnecting")
        states.append(worker.state)
        assert worker.reason
        wait_for(lambda: "retrying" in worker.reason, 10, "a failed retry")
        frames_before = worker.frames
        camera.start()  # Back on the same port.
        wait_for(
            lambda: worker.state == "live" and worker.frames > frames_before + 5,
            20,
            "the camera to come back",
        )
    finally:
        worker.request_stop()
        worker.join(5)
        camera.stop()
    assert states == ["reconnecting"]


def test_settings_apply_on_next_frame(parts: dict[str, Any], tmp_path: Path) -> None:
    worker = make_worker(parts, str(write_video(tmp_path / "v.avi")), active=True)
    worker.start()
    try:
        wait_for(lambda: worker.processed > 3, 10, "detection running")
        pipeline = worker._pipeline
        assert pipeline is not None
        worker.update(sensitivity=77, min_area=321)
        wait_for(lambda: pipeline.method.sensitivity == 77, 5, "the new sensitivity")
        assert pipeline.blobs.min_area == 321
        worker.update(method="frame-difference")
        wait_for(
            lambda: (
                worker._pipeline is not None
                and worker._pipeline.config.method == "frame-difference"
            ),
            5,
            "the new method",
        )
        worker.set_active(False)
        wait_for(lambda: worker._pipeline is None, 5, "detection to stop")
    finally:
        worker.request_stop()
        worker.join(5)


def test_a_camera_activated_while_the_kernels_compile_says_so_and_its_picture_goes_on(
    parts: dict[str, Any], tmp_path: Path
) -> None:
    # A first start compiles the kernels for seconds; a camera that ran into them froze
    # its picture meanwhile, and nothing said why detection had not begun.
    worker = make_worker(parts, str(write_video(tmp_path / "v.avi")), active=True)
    DETECTION_WARMING.set()
    try:
        worker.start()
        wait_for(lambda: worker.reason == PREPARING, 10, "the reason")
        shown = worker.frames
        wait_for(lambda: worker.frames >= shown + 10, 10, "the picture going on")
        assert worker.state == "live" and worker.processed == 0
        DETECTION_WARMING.clear()
        wait_for(lambda: worker.processed > 3, 10, "detection once they are ready")
        assert worker.reason == ""
        # Stopped while it waited: nothing is left to say.
        worker.set_active(False)
        wait_for(lambda: worker._pipeline is None, 5, "detection to stop")
        DETECTION_WARMING.set()
        worker.set_active(True)
        wait_for(lambda: worker.reason == PREPARING, 10, "the reason again")
        worker.set_active(False)
        wait_for(lambda: worker.reason == "", 10, "the reason gone")
    finally:
        DETECTION_WARMING.clear()
        worker.request_stop()
        worker.join(5)


def test_each_new_object_in_an_open_event_gives_its_own_alarm(
    parts: dict[str, Any], tmp_path: Path
) -> None:
    # One walker from frame 3, a second from frame 20, both gone at frame 50: one event.
    scene = Scene(
        name="two", size=(320, 240), fps=15.0, frames=70,
        objects=(
            MovingObject((20, 60), (60.0, 0.0), (28, 40), 220, first_frame=3, last_frame=50),
            MovingObject((20, 160), (50.0, 0.0), (28, 40), 30, first_frame=20, last_frame=50),
        ),
    )  # fmt: skip
    video = write_scene_video(scene, tmp_path / "two.avi")
    worker = make_worker(parts, str(video))
    received = _messages_until_motion_end(parts, worker)
    alarms = [m for m in received if m["type"] == "alarm"]
    assert len(alarms) == 2
    assert alarms[0]["event_id"] == alarms[1]["event_id"]
    assert len(alarms[1]["boxes"]) == 2
    assert alarms[0]["snapshot"] != alarms[1]["snapshot"]


def test_a_stop_between_frames_handles_no_further_frame(
    parts: dict[str, Any], tmp_path: Path
) -> None:
    """Stopped while it waits for its next frame (most of a frame period), a camera
    handles none after: no frame, and so no alarm or snapshot, once it was told to stop."""
    assert 1 / FPS <= PLAIN_SLEEP_S  # The wait between frames is the plain sleep's.
    worker = make_worker(parts, str(write_video(tmp_path / "v.avi")), active=True)
    worker.start()
    try:
        wait_for(lambda: worker.processed > 3, 10, "detection running")
        seen = worker.frames
        wait_for(lambda: worker.frames > seen, 5, "the next frame")
        worker.request_stop()  # Just after a frame: the worker is about to wait.
        stopped_at = worker.frames
    finally:
        worker.request_stop()
        assert worker.join(5)
    assert worker.frames == stopped_at


# Someone walks across the whole view, in view the moment Activate is pressed.
WALKING_ACROSS = Scene(
    name="walking-across",
    fps=25.0,
    frames=250,
    objects=(MovingObject((-20, 100), (60.0, 0.0), (40, 40), 200),),
)


def _detections_after_activate(
    tmp_path: Path, glance_s: float, stopped_before: bool = False
) -> dict[int, int]:
    """Run the camera idle for 2.2 s, activate it (``stopped_before``: activate it at
    1.2 s, stop it at 2.2 s and activate it again at once), and count the objects on each
    of its frames for the next 2 s (frame number -> detections)."""
    parts = worker_parts(tmp_path, scene_glance_s=glance_s)
    video = write_scene_video(WALKING_ACROSS, tmp_path / "walking.avi")
    worker = make_worker(parts, str(video))
    seen: dict[int, int] = {}
    worker.start()
    try:
        if stopped_before:
            wait_for(lambda: worker.frames >= 30, 10, "the camera to run idle")
            worker.set_active(True)
            wait_for(lambda: worker.frames >= 55, 10, "the camera to detect")
            worker.set_active(False)
            stopped_at = worker.frames
            wait_for(lambda: worker.frames > stopped_at, 10, "a frame after the stop")
        else:
            wait_for(lambda: worker.frames >= 55, 10, "the camera to run idle")
        processed = worker.processed
        worker.set_active(True)
        wait_for(lambda: worker.processed > processed, 10, "detection to start")
        until = time.monotonic() + 2.0
        while time.monotonic() < until:
            latest = worker.hub.latest
            if latest is not None:
                seen[latest.seq] = len(latest.detections)
            time.sleep(0.005)
    finally:
        worker.request_stop()
        worker.join(5)
    return seen


def test_someone_in_view_at_activate_is_motion_and_leaves_no_ghost(tmp_path: Path) -> None:
    # Nine glances 0.2 s apart: the walker covers each pixel for a third of them.
    seen = _detections_after_activate(tmp_path / "glances", glance_s=0.2)
    assert len(seen) >= 30, "the frames after Activate were not seen"
    assert max(seen.values()) == 1, seen  # The walker, and nothing where it stood.
    assert sum(count == 1 for count in seen.values()) >= 0.9 * len(seen), seen
    # Learning the frame at Activate instead (one glance is too few to tell the scene):
    # where the walker stood, a ghost.
    first_frame = _detections_after_activate(tmp_path / "no-glances", glance_s=1000.0)
    assert max(first_frame.values()) >= 2, first_frame


def test_activate_again_right_after_stop_starts_from_the_scene(tmp_path: Path) -> None:
    # A Stop and an Activate a moment later, the walker in view: the glances go on
    # while the camera detects, so the scene is known, and where the walker stood at
    # the second Activate there is no ghost.
    seen = _detections_after_activate(tmp_path, glance_s=0.2, stopped_before=True)
    assert len(seen) >= 30, "the frames after Activate were not seen"
    assert max(seen.values()) == 1, seen


def test_a_lamp_that_came_on_just_before_activate_is_not_motion(parts: dict[str, Any]) -> None:
    # A lamp comes on over part of the view, and Activate follows two glances later.
    # The glances' median showed it off, so the lit patch was an object for half a
    # second; the newest glances and the frame at Activate show it is the scene.
    parts["settings"].scene_glance_s = 0.01
    worker = make_worker(parts, "demo")
    scene = Scene("lamp", fps=25.0, frames=50)
    light = lamplight(scene.size, 50.0, 35.0, (0.3, 0.4))
    for index in range(12):
        picture = scene.frame(index)
        worker._handle(DecodedFrame(lit(picture, light) if index >= 10 else picture))
        time.sleep(0.012)  # Each frame a glance.
    worker.set_active(True)
    objects = []
    for index in range(12, scene.frames):
        worker._handle(DecodedFrame(lit(scene.frame(index), light)))
        objects.append(worker.objects)
    assert worker.processed == scene.frames - 12
    assert max(objects) == 0, objects


def test_a_picture_that_changes_size_while_detecting_does_not_fail_the_next_activate(
    parts: dict[str, Any],
) -> None:
    # A stream that switches from 4:3 to 16:9 while the camera detects: the glances
    # then held two sizes, and an Activate after a Stop failed stacking them.
    parts["settings"].scene_glance_s = 0.01
    worker = make_worker(parts, "demo")
    rng = np.random.default_rng(1)

    def frame(width: int, height: int) -> DecodedFrame:
        return DecodedFrame(rng.integers(100, 110, (height, width, 3), dtype=np.uint8))

    worker.set_active(True)
    for size in [(640, 480)] * 12 + [(1280, 720)] * 3:
        worker._handle(frame(*size))
        time.sleep(0.012)
    worker.set_active(False)
    worker._handle(frame(1280, 720))
    worker.set_active(True)
    processed = worker.processed
    worker._handle(frame(1280, 720))  # Activate again: detection starts, no failure.
    assert worker.processed == processed + 1


def test_detection_counts_time_at_the_rate_the_camera_sends(parts: dict[str, Any]) -> None:
    # An MJPEG stream's header says nothing of its rate (OpenCV takes 25): a camera
    # sending 10 frames a second would keep a waiting person 12.5 s instead of 5.
    camera = MjpegCamera(fps=10.0).start()
    worker = make_worker(parts, camera.url)
    worker.start()
    try:
        wait_for(lambda: worker.frames >= 20, 15, "the camera to run")
        worker.set_active(True)
        wait_for(lambda: worker.processed > 0, 15, "detection to start")
        pipeline = worker._pipeline
        assert pipeline is not None
        assert 8.5 <= pipeline.fps <= 11.5, pipeline.fps
        assert worker._source is not None and worker._source.fps != pytest.approx(10.0, abs=1.5)
        # A reconnect starts the count of frames again: the rate is still the measured
        # one (a person stopping after a network hiccup was kept 13 s, not 5).
        camera.stop()
        wait_for(lambda: worker.state == "reconnecting", 15, "the camera to be lost")
        camera.start()
        wait_for(lambda: worker.state == "live", 15, "the camera back")
        processed = worker.processed
        wait_for(lambda: worker.processed > processed, 15, "detection again")
        pipeline = worker._pipeline
        assert pipeline is not None and 8.5 <= pipeline.fps <= 11.5, pipeline.fps
    finally:
        worker.request_stop()
        worker.join(5)
        camera.stop()
