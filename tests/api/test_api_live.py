"""Activate -> alarm on /ws, MJPEG frames, histogram stream, sensitivity, snapshots and zip."""

from __future__ import annotations

import io
import time
import zipfile
from collections.abc import Callable
from pathlib import Path

import cv2
import httpx
import numpy as np

from app.storage import Database
from tests.api.vigil_livekit import (
    FPS,
    MOTION_FIRST,
    MOTION_LAST,
    Running,
    WsClient,
    add_camera,
    background,
    frame_at,
    free_port,
    read_mjpeg_frames,
    wait_for,
)


def _add(server: Running, video: Path, **extra: object) -> int:
    cam_id = add_camera(server.base, f"file://{video}", **extra)
    wait_for(
        lambda: httpx.get(f"{server.base}/api/cameras/{cam_id}").json()["state"] == "live",
        10,
        "the camera to go live",
    )
    return cam_id


def test_activate_gives_alarm_snapshot_and_motion_end(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    server = serve()
    cam = _add(server, motion_video)
    with WsClient(server.ws) as ws:
        time.sleep(0.5)  # Watched but not active: no detection, no alarm.
        assert ws.of_type("alarm") == []
        assert httpx.get(f"{server.base}/api/cameras/{cam}").json()["processed"] == 0
        httpx.post(f"{server.base}/api/cameras/{cam}/activate").raise_for_status()
        (alarm,) = ws.wait("alarm", 15, camera_id=cam)[:1]
        assert alarm["boxes"] and all(len(b) == 4 for b in alarm["boxes"])
        _x, y, _w, h = alarm["boxes"][0]
        assert 60 <= y + h / 2 <= 150, "the box should be on the square's row"
        snapshot = httpx.get(f"{server.base}{alarm['snapshot']}")
        assert snapshot.status_code == 200 and snapshot.content[:2] == b"\xff\xd8"
        assert httpx.get(f"{server.base}{alarm['difference']}").status_code == 200
        ended = ws.wait("motion_end", 15, camera_id=cam)[0]
        assert ended["event_id"] == alarm["event_id"]
        statuses = ws.of_type("status", camera_id=cam)
        assert any(s["state"] == "live" and s["fps"] > 0 for s in statuses)
        # The file loops: the next crossing is a new movement, a new alarm.
        ws.wait("alarm", 15, count=2, camera_id=cam)
        httpx.post(f"{server.base}/api/cameras/{cam}/stop").raise_for_status()
    events = httpx.get(f"{server.base}/api/events", params={"camera_id": cam}).json()
    assert len(events) >= 2
    assert events[-1]["id"] == alarm["event_id"] and events[-1]["ended_at"] is not None


def test_deleting_a_camera_mid_event_ends_the_event_for_clients(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    server = serve()
    cam = _add(server, motion_video)
    with WsClient(server.ws) as ws:
        httpx.post(f"{server.base}/api/cameras/{cam}/activate").raise_for_status()
        (alarm,) = ws.wait("alarm", 15, camera_id=cam)[:1]
        assert httpx.delete(f"{server.base}/api/cameras/{cam}").status_code == 204
        ended = ws.wait("motion_end", 10, camera_id=cam)[0]
        assert ended["event_id"] == alarm["event_id"]
    (event,) = [
        e
        for e in httpx.get(f"{server.base}/api/events", params={"camera_id": cam}).json()
        if e["id"] == alarm["event_id"]
    ]
    assert event["ended_at"] is not None


def test_mjpeg_frames_decode_and_histogram(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    server = serve()
    cam = _add(server, motion_video)
    with httpx.stream("GET", f"{server.base}/api/cameras/{cam}/stream.mjpg", timeout=10) as r:
        assert r.headers["content-type"].startswith("multipart/x-mixed-replace")
        frames = read_mjpeg_frames(r.iter_bytes(), 5)
    assert all(f.shape == (240, 320, 3) for f in frames)
    with httpx.stream("GET", f"{server.base}/api/cameras/{cam}/histogram.mjpg", timeout=10) as r:
        hists = read_mjpeg_frames(r.iter_bytes(), 3)
    assert all(h.shape == (120, 256, 3) for h in hists)
    single = httpx.get(f"{server.base}/api/cameras/{cam}/frame.jpg")
    assert single.headers["content-type"] == "image/jpeg"
    image = cv2.imdecode(np.frombuffer(single.content, np.uint8), cv2.IMREAD_COLOR)
    assert image is not None and image.shape == (240, 320, 3)
    assert httpx.get(f"{server.base}/api/cameras/999/stream.mjpg").status_code == 404


def test_a_viewer_that_leaves_is_let_go_with_frames_coming_or_not(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    """A camera process sends pictures only while someone watches: a viewer that closed
    its stream must stop counting, whether frames come or not, and one still there
    must go on counting past the route's wait for a frame."""
    server = serve()
    cameras = server.server.config.app.state.services.cameras
    live = _add(server, motion_video)
    port = free_port()  # Nothing listens there: a camera that sends no frames.
    silent = add_camera(server.base, f"http://127.0.0.1:{port}/video.mjpg", name="gone")
    for camera_id, parts in ((live, 3), (silent, 0)):
        hub = cameras.get(camera_id).hub
        url = f"{server.base}/api/cameras/{camera_id}/stream.mjpg"
        with httpx.stream("GET", url, timeout=10) as r:
            chunks = r.iter_bytes()  # Held: a generator let go closes the connection.
            if parts:
                read_mjpeg_frames(chunks, parts)
            wait_for(lambda hub=hub: hub.watching["picture"] == 1, 5, "the viewer to count")
            time.sleep(1.5)  # Past the route's one-second wait for a frame.
            assert hub.watching["picture"] == 1, "a viewer still there was let go"
        wait_for(lambda hub=hub: hub.watching["picture"] == 0, 3, "the viewer to be let go")


def test_stream_shows_red_boxes_when_active(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    server = serve()
    cam = _add(server, motion_video)
    httpx.post(f"{server.base}/api/cameras/{cam}/activate").raise_for_status()

    def red_pixels() -> int:
        data = httpx.get(f"{server.base}/api/cameras/{cam}/frame.jpg").content
        decoded = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
        assert decoded is not None
        bgr = decoded.astype(int)
        return int(((bgr[..., 2] > 180) & (bgr[..., 1] < 80) & (bgr[..., 0] < 80)).sum())

    wait_for(lambda: red_pixels() > 50, 15, "a red box on the live picture")


def test_sensitivity_change_takes_effect(serve: Callable[..., Running], motion_video: Path) -> None:
    server = serve()
    cam = _add(server, motion_video, sensitivity=255)  # Nothing differs by 255 grey levels.
    with WsClient(server.ws) as ws:
        httpx.post(f"{server.base}/api/cameras/{cam}/activate").raise_for_status()
        # More than a loop of the video (45 frames), the square crossing in it: no alarm.
        wait_for(
            lambda: httpx.get(f"{server.base}/api/cameras/{cam}").json()["processed"] > 50,
            20,
            "a loop processed",
        )
        assert ws.of_type("alarm") == []
        httpx.patch(f"{server.base}/api/cameras/{cam}", json={"sensitivity": 25}).raise_for_status()
        ws.wait("alarm", 15, camera_id=cam)
    assert httpx.get(f"{server.base}/api/cameras/{cam}").json()["sensitivity"] == 25


def test_snapshots_listing_zip_and_delete(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    server = serve()
    base = server.base
    cam = _add(server, motion_video)
    started = time.time()
    with WsClient(server.ws) as ws:
        httpx.post(f"{base}/api/cameras/{cam}/activate").raise_for_status()
        ws.wait("alarm", 15, camera_id=cam)
    httpx.post(f"{base}/api/cameras/{cam}/stop").raise_for_status()
    listed = httpx.get(f"{base}/api/snapshots", params={"camera_id": cam}).json()
    assert {s["kind"] for s in listed} == {"frame", "difference"}
    assert all(s["ts"] >= started - 1 for s in listed)
    assert httpx.get(f"{base}/api/snapshots", params={"camera_id": cam + 1}).json() == []
    assert httpx.get(f"{base}/api/snapshots", params={"since": time.time() + 60}).json() == []
    frames_only = httpx.get(f"{base}/api/snapshots", params={"kind": "frame"}).json()
    assert frames_only and all(s["kind"] == "frame" for s in frames_only)

    with httpx.stream("GET", f"{base}/api/snapshots.zip", params={"camera_id": cam}) as r:
        assert r.headers["content-type"] == "application/zip"
        assert "attachment" in r.headers["content-disposition"]
        body = b"".join(r.iter_bytes())
    archive = zipfile.ZipFile(io.BytesIO(body))
    assert archive.testzip() is None
    assert len(archive.namelist()) == len(listed)
    first = archive.read(archive.namelist()[0])
    assert cv2.imdecode(np.frombuffer(first, np.uint8), cv2.IMREAD_COLOR) is not None
    picked = httpx.get(f"{base}/api/snapshots.zip", params={"ids": str(listed[0]["id"])})
    assert len(zipfile.ZipFile(io.BytesIO(picked.content)).namelist()) == 1
    two = [str(s["id"]) for s in listed[:2]]
    for params in ({"ids": ",".join(two)}, [("ids", two[0]), ("ids", two[1])]):
        picked = httpx.get(f"{base}/api/snapshots.zip", params=params)
        assert len(zipfile.ZipFile(io.BytesIO(picked.content)).namelist()) == 2, params
    # A selection of none is an empty zip, not the whole gallery.
    for empty in ("", ",", " "):
        picked = httpx.get(f"{base}/api/snapshots.zip", params={"ids": empty})
        assert zipfile.ZipFile(io.BytesIO(picked.content)).namelist() == [], repr(empty)
    refused = httpx.get(f"{base}/api/snapshots.zip", params={"ids": "-1"})
    assert refused.status_code == 422 and "from 0 to" in refused.json()["detail"]

    ids = [s["id"] for s in listed]
    deleted = httpx.post(f"{base}/api/snapshots/delete", json={"ids": ids}).json()
    assert sorted(deleted["deleted"]) == sorted(ids)
    assert httpx.get(f"{base}/api/snapshots/{ids[0]}.jpg").status_code == 404
    assert httpx.get(f"{base}/api/snapshots", params={"camera_id": cam}).json() == []


def test_shutdown_is_prompt_with_streams_open(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    import threading

    server = serve()
    cam = _add(server, motion_video)
    got_frames = threading.Event()

    def watch() -> None:
        try:
            with httpx.stream(
                "GET", f"{server.base}/api/cameras/{cam}/stream.mjpg", timeout=30
            ) as r:
                for _ in r.iter_bytes():
                    got_frames.set()
        except httpx.HTTPError:
            pass

    viewers = [threading.Thread(target=watch, daemon=True) for _ in range(2)]
    for viewer in viewers:
        viewer.start()
    assert got_frames.wait(10)
    with WsClient(server.ws):
        took = server.stop()
    assert took < 6, f"uvicorn took {took:.1f} s to stop with streams open"
    for viewer in viewers:
        viewer.join(5)
        assert not viewer.is_alive()


def test_network_camera_state_is_visible_and_recovers(serve: Callable[..., Running]) -> None:
    from tests.api.vigil_livekit import MjpegCamera

    camera = MjpegCamera().start()
    server = serve()
    try:
        with WsClient(server.ws) as ws:
            response = httpx.post(
                f"{server.base}/api/cameras", json={"name": "gate", "source": camera.url}
            )
            cam = response.json()["id"]
            ws.wait("status", 15, camera_id=cam, state="live")
            camera.stop()
            lost = ws.wait("status", 15, camera_id=cam, state="reconnecting")[0]
            assert lost["reason"]
            shown = httpx.get(f"{server.base}/api/cameras/{cam}").json()
            assert shown["state"] == "reconnecting" and shown["reason"]
            live_before = len(ws.of_type("status", camera_id=cam, state="live"))
            camera.start()
            wait_for(
                lambda: len(ws.of_type("status", camera_id=cam, state="live")) > live_before,
                20,
                "the camera to come back live",
            )
            back = wait_for(
                lambda: (
                    (c := httpx.get(f"{server.base}/api/cameras/{cam}").json())["fps"] > 0 and c
                ),
                10,
                "a measured frame rate",
            )
            assert back["state"] == "live"
    finally:
        camera.stop()


def test_motion_end_gives_the_duration_the_event_is_listed_with(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    """An event lasts from its first moving frame to its last: the ``motion_end`` message
    and the row of ``/api/events`` (which the page shows after a reload) say the same,
    and neither counts the quiet seconds that it takes to tell the event is over."""
    server = serve()
    cam = _add(server, motion_video)
    with WsClient(server.ws) as ws:
        httpx.post(f"{server.base}/api/cameras/{cam}/activate").raise_for_status()
        (alarm,) = ws.wait("alarm", 15, camera_id=cam)[:1]
        ended = ws.wait("motion_end", 15, camera_id=cam)[0]
    (event,) = [
        e
        for e in httpx.get(f"{server.base}/api/events", params={"camera_id": cam}).json()
        if e["id"] == alarm["event_id"]
    ]
    assert event["started_at"] == alarm["ts"]
    assert ended["ts"] == event["ended_at"]
    assert ended["duration_s"] == round(event["ended_at"] - event["started_at"], 3)
    # The square moves for 2 s; the event ends after quiet_s (0.5 s) without motion,
    # which is when the message goes out, not when the event ended.
    assert 1.0 < ended["duration_s"] < (MOTION_LAST - MOTION_FIRST + 1) / FPS + 0.2
    assert ended["_received"] - event["ended_at"] >= 0.4


def test_a_folder_of_images_is_a_camera(serve: Callable[..., Running], tmp_path: Path) -> None:
    """DESIGN.md's file sources include a folder of images: looped by name, at 25 fps."""
    folder = tmp_path / "frames"
    folder.mkdir()
    base = background()
    for index in range(45):  # Both kinds of picture; 2 sorts before 10.
        cv2.imwrite(str(folder / f"{index}.{'png' if index % 2 else 'jpg'}"), frame_at(index, base))
    (folder / "notes.txt").write_text("not a frame")
    server = serve()
    cam = _add(server, folder)
    camera = httpx.get(f"{server.base}/api/cameras/{cam}").json()
    assert camera["source_fps"] == 25.0 and camera["reason"] == ""
    with WsClient(server.ws) as ws:
        httpx.post(f"{server.base}/api/cameras/{cam}/activate").raise_for_status()
        (alarm,) = ws.wait("alarm", 15, camera_id=cam)[:1]
        ws.wait("motion_end", 15, camera_id=cam)
        ws.wait("alarm", 15, count=2, camera_id=cam)  # The folder loops.
    _x, y, _w, h = alarm["boxes"][0]
    assert 60 <= y + h / 2 <= 150, "the box should be on the square's row"
    frame = httpx.get(f"{server.base}/api/cameras/{cam}/frame.jpg", timeout=10)
    picture = cv2.imdecode(np.frombuffer(frame.content, np.uint8), cv2.IMREAD_COLOR)
    assert picture.shape == (240, 320, 3)


def test_event_filters_select_the_events_that_overlap_the_window(
    serve: Callable[..., Running], tmp_path: Path
) -> None:
    """``since``/``until`` select the events that were going on at some time between them:
    one that started before ``since`` and ended after it, or is still open, is in."""
    data = tmp_path / "data"
    server = serve(data)
    db = Database(data / "vigil.db")
    try:
        before = db.add_event(1, 50.0, [], 10.0)
        db.end_event(before, 60.0, 10.0)
        across = db.add_event(1, 100.0, [], 10.0)
        db.end_event(across, 110.0, 10.0)
        running = db.add_event(1, 200.0, [], 10.0)  # Still open: ended_at is null.
    finally:
        db.close()

    def listed(**window: float) -> list[int]:
        response = httpx.get(f"{server.base}/api/events", params=window)
        assert response.status_code == 200, response.text
        return [e["id"] for e in response.json()]

    assert listed(since=105) == [running, across]
    assert listed(since=105, until=150) == [across]
    assert listed(until=105) == [across, before]
    assert listed(since=61, until=99) == []
    assert listed(since=10_000) == [running]
    assert listed(since=60, until=60) == [before]
    assert listed(since=110, until=200) == [running, across]
