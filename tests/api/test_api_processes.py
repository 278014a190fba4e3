"""Cameras spread over camera processes; one that dies is started again with its cameras."""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path

import cv2
import httpx
import numpy as np
import psutil

from tests.api.vigil_livekit import Running, WsClient, add_camera, wait_for, write_video


def _camera(base: str, cam: int) -> dict:
    return dict(httpx.get(f"{base}/api/cameras/{cam}").json())


def _camera_processes() -> list[psutil.Process]:
    """The camera processes of the servers this test process runs (uvicorn runs in a
    thread here): the children of its forkserver."""
    return [
        camera
        for child in psutil.Process().children()
        if "forkserver" in " ".join(child.cmdline())
        for camera in child.children()
        if camera.is_running()
    ]


def test_cameras_are_spread_over_the_processes_and_each_raises_alarms(
    serve: Callable[..., Running], motion_video: Path, tmp_path: Path
) -> None:
    server = serve(camera_processes=2)
    other = write_video(tmp_path / "other.avi")
    with WsClient(server.ws) as ws:
        cams = [
            add_camera(server.base, f"file://{motion_video}", "porch", activate=True),
            add_camera(server.base, f"file://{other}", "gate", activate=True),
        ]
        for cam in cams:
            ws.wait("alarm", 30, camera_id=cam)
    assert {_camera(server.base, cam)["process"] for cam in cams} == {0, 1}
    assert len(_camera_processes()) == 2


def test_camera_processes_start_with_their_first_camera(serve: Callable[..., Running]) -> None:
    server = serve(camera_processes=3)
    assert _camera_processes() == []  # No camera yet: no idle process either.
    first = add_camera(server.base, "demo", "one")
    wait_for(lambda: len(_camera_processes()) == 1, 10, "one camera process")
    second = add_camera(server.base, "demo", "two")
    wait_for(lambda: len(_camera_processes()) == 2, 10, "a second camera process")
    assert [_camera(server.base, cam)["process"] for cam in (first, second)] == [0, 1]
    # A running process left without cameras takes the next one; no third is started.
    assert httpx.delete(f"{server.base}/api/cameras/{first}").status_code == 204
    third = add_camera(server.base, "demo", "three")
    assert _camera(server.base, third)["process"] == 0
    wait_for(lambda: _camera(server.base, third)["state"] == "live", 10, "the third camera")
    assert len(_camera_processes()) == 2


def test_a_camera_process_that_dies_is_restarted_with_its_cameras(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    server = serve(camera_processes=1)
    with WsClient(server.ws) as ws:
        cam = add_camera(server.base, f"file://{motion_video}", "porch", activate=True)
        (alarm,) = ws.wait("alarm", 30, camera_id=cam)
        (host,) = _camera_processes()
        host.kill()  # As a decoder crash would end it, mid-event.
        down = ws.wait("status", 10, camera_id=cam, state="error")[0]
        assert "camera process died (signal 9, SIGKILL)" in down["reason"]
        # The event the dead process left open is ended by its successor.
        ws.wait("motion_end", 20, event_id=alarm["event_id"])
        alarms_before = len(ws.of_type("alarm", camera_id=cam))
        wait_for(
            lambda: len(ws.of_type("alarm", camera_id=cam)) > alarms_before,
            30,
            "alarms from the restarted camera process",
        )
    view = _camera(server.base, cam)
    assert view["state"] == "live" and view["active"]
    (again,) = _camera_processes()
    assert again.pid != host.pid


def _frames_from(url: str, received: list[int], stop: threading.Event) -> None:
    """Count the JPEG parts of an MJPEG stream until ``stop``."""
    with httpx.stream("GET", url, timeout=30) as response:
        for chunk in response.iter_bytes():
            received[0] += chunk.count(b"\xff\xd8")
            if stop.is_set():
                return


def test_an_open_stream_carries_on_through_a_restart_and_a_new_source(
    serve: Callable[..., Running], motion_video: Path, tmp_path: Path
) -> None:
    server = serve(camera_processes=1)
    cam = add_camera(server.base, f"file://{motion_video}", "porch", activate=True)
    url = f"{server.base}/api/cameras/{cam}/stream.mjpg"
    received = [0]
    stop = threading.Event()
    viewer = threading.Thread(target=_frames_from, args=(url, received, stop), daemon=True)
    viewer.start()
    try:
        wait_for(lambda: received[0] > 10, 20, "frames before the crash")
        (host,) = _camera_processes()
        host.kill()
        wait_for(lambda: _camera(server.base, cam)["state"] == "error", 10, "the crash seen")
        before = received[0]
        wait_for(lambda: received[0] > before + 10, 30, "frames after the restart")

        other = tmp_path / "other.avi"  # Smaller than the first: its frames are told apart.
        writer = cv2.VideoWriter(str(other), cv2.VideoWriter.fourcc(*"MJPG"), 15, (160, 120))
        for _ in range(30):
            writer.write(np.full((120, 160, 3), 90, np.uint8))
        writer.release()
        changed = httpx.patch(
            f"{server.base}/api/cameras/{cam}", json={"source": f"file://{other}"}
        )
        changed.raise_for_status()

        # The old stream ends with its worker; a new viewer gets the new source's frames.
        def new_source_shown() -> bool:
            fresh = httpx.get(f"{server.base}/api/cameras/{cam}/frame.jpg", timeout=10)
            if fresh.status_code != 200 or fresh.content[:2] != b"\xff\xd8":
                return False
            picture = cv2.imdecode(np.frombuffer(fresh.content, np.uint8), cv2.IMREAD_COLOR)
            return picture is not None and picture.shape[:2] == (120, 160)

        wait_for(new_source_shown, 15, "a frame of the new source")
    finally:
        stop.set()
