"""Cameras that misbehave as real ones do, and a worker that fails: each is shown, then recovers.

Timeouts and backoff are the shipped defaults, so "back within 5 s of the camera
returning" is what a user gets.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from app.core.config import Settings
from app.workers.camera import CameraWorker
from tests.api.vigil_livekit import MjpegCamera, wait_for, write_video
from tests.workers.conftest import make_worker, worker_parts

RESUME_S = 5.0
"""The promise: a camera that comes back is live again within this."""

SHIPPED = {
    name: Settings.model_fields[name].default
    for name in ("reconnect_min_s", "reconnect_max_s", "open_timeout_ms", "read_timeout_ms")
}


@pytest.fixture
def shipped_parts(tmp_path: Path) -> dict[str, Any]:
    return worker_parts(tmp_path, **SHIPPED)


@pytest.fixture
def camera() -> Iterator[MjpegCamera]:
    camera = MjpegCamera().start()
    yield camera
    camera.stop()


class StatusLog:
    """The worker's ``status`` messages, as /ws clients receive them."""

    def __init__(self, parts: dict[str, Any]) -> None:
        self.loop = asyncio.new_event_loop()
        self.queue = self.loop.run_until_complete(self._subscribe(parts))

    @staticmethod
    async def _subscribe(parts: dict[str, Any]) -> asyncio.Queue[Any]:
        return parts["bus"].subscribe()

    def states(self) -> list[tuple[str, str]]:
        """(state, reason) of every status message so far, in order."""
        self.loop.run_until_complete(asyncio.sleep(0))
        seen = []
        while not self.queue.empty():
            message = self.queue.get_nowait()
            if message is not None and message["type"] == "status":
                seen.append((message["state"], message["reason"]))
        return seen


def resumes(worker: CameraWorker, camera: MjpegCamera) -> float:
    """Let the camera behave again; seconds until the worker has new frames."""
    camera.mode = "normal"
    started = time.monotonic()
    frames = worker.frames
    wait_for(
        lambda: worker.state == "live" and worker.frames > frames + 3,
        RESUME_S + 10,
        "the camera to come back",
    )
    return time.monotonic() - started


@contextmanager
def running(worker: CameraWorker) -> Iterator[CameraWorker]:
    worker.start()
    try:
        yield worker
    finally:
        worker.request_stop()
        worker.join(5)


def test_camera_that_stalls_mid_frame_is_lost_then_resumes(
    shipped_parts: dict[str, Any], camera: MjpegCamera
) -> None:
    log = StatusLog(shipped_parts)
    with running(make_worker(shipped_parts, camera.url)) as worker:
        wait_for(lambda: worker.state == "live" and worker.frames > 5, 15, "live")
        camera.mode = "stall"
        wait_for(lambda: worker.state == "reconnecting", 10, "the stall to be noticed")
        time.sleep(4)  # Reopening meets the stall again: still lost, not live.
        assert worker.state == "reconnecting", worker.state
        assert resumes(worker, camera) < RESUME_S
    states = [state for state, _ in log.states()]
    # Clients were told both: the camera was lost, then live again.
    assert "live" in states[states.index("reconnecting") :]


def test_camera_that_never_answers_shows_error_then_resumes(
    shipped_parts: dict[str, Any], camera: MjpegCamera
) -> None:
    camera.mode = "silent"
    log = StatusLog(shipped_parts)
    with running(make_worker(shipped_parts, camera.url)) as worker:
        wait_for(lambda: worker.state == "error", 10, "the open timeout")
        assert "cannot open stream from 127.0.0.1" in worker.reason
        time.sleep(6)  # Long enough for the backoff to reach its longest.
        assert resumes(worker, camera) < RESUME_S
    states = log.states()
    failed = [
        i
        for i, (state, reason) in enumerate(states)
        if state == "error" and "cannot open" in reason
    ]
    assert failed
    assert "live" in [state for state, _ in states[failed[0] :]]


def test_camera_sending_garbage_is_reported_then_resumes(
    shipped_parts: dict[str, Any], camera: MjpegCamera
) -> None:
    with running(make_worker(shipped_parts, camera.url)) as worker:
        wait_for(lambda: worker.state == "live" and worker.frames > 5, 15, "live")
        frames = worker.frames
        camera.mode = "garbage"
        wait_for(lambda: worker.state != "live", 15, "the garbage to be noticed")
        assert worker.frames - frames < 60, "garbage must not count as frames"
        assert "JPEG" in worker.reason or "cannot open" in worker.reason, worker.reason
        assert resumes(worker, camera) < RESUME_S


def test_worker_that_keeps_failing_settles_in_error_saying_why(
    parts: dict[str, Any], tmp_path: Path
) -> None:
    worker = make_worker(parts, str(write_video(tmp_path / "v.avi")), active=True)
    parts["db"].close()  # The database is gone: every alarm fails inside the worker.
    with running(worker):
        wait_for(lambda: worker.state == "error", 30, "the error state")
        assert "worker failed 3 times in a row" in worker.reason
        assert "database" in worker.reason.lower(), worker.reason
        assert worker._thread.is_alive(), "the worker keeps trying"


def test_camera_whose_pictures_never_decode_shows_error_not_live(
    tmp_path: Path,
) -> None:
    """A file whose every JPEG has a frame header but no picture (its scan marker gone):
    the camera is never live, even idle (which decodes nothing else), and settles in
    error saying why; it keeps retrying."""
    video = write_video(tmp_path / "v.avi")
    broken = tmp_path / "broken.avi"
    broken.write_bytes(video.read_bytes().replace(b"\xff\xda", b"\xff\xd9"))
    parts = worker_parts(tmp_path, bad_frames_limit=5)
    log = StatusLog(parts)
    with running(make_worker(parts, f"file://{broken}")) as worker:
        wait_for(lambda: worker.state == "error", 15, "the error state")
        assert "does not decode" in worker.reason and "retrying" in worker.reason
        assert "live" not in {state for state, _ in log.states()}
        assert worker._thread.is_alive(), "it keeps trying"
