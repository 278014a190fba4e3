"""WS /ws/live against a real uvicorn and camera process: the binary messages, the camera's
own JPEG byte for byte, the detections and mask as data, watching and unwatching,
backpressure, and the same session and origin rules as /ws."""

from __future__ import annotations

import base64
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import httpx
import numpy as np
import pytest

from app.workers.hub import Picture
from tests.api.test_api_access import ws_status
from tests.api.vigil_live_frames import LiveViewer, StuckViewer
from tests.api.vigil_livekit import (
    FPS,
    HEIGHT,
    WIDTH,
    MjpegCamera,
    Running,
    add_camera,
    background,
    frame_at,
    square_box,
    wait_for,
)

LOOP = 45
"""Frames in the test video's loop (``write_video``)."""


def _live(server: Running, source: str, **extra: Any) -> int:
    cam = add_camera(server.base, source, **extra)
    wait_for(
        lambda: httpx.get(f"{server.base}/api/cameras/{cam}").json()["state"] == "live",
        10,
        "the camera to go live",
    )
    return cam


def _url(server: Running) -> str:
    return server.ws + "/live"


def _iou(a: list[int], b: tuple[int, int, int, int]) -> float:
    ix = max(0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    iy = max(0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    inter = ix * iy
    return inter / (a[2] * a[3] + b[2] * b[3] - inter)


def file_packets(video: Path) -> list[bytes]:
    """The JPEGs of an MJPG AVI as the file holds them, in order."""
    capture = cv2.VideoCapture(str(video), cv2.CAP_FFMPEG)
    assert capture.set(cv2.CAP_PROP_FORMAT, -1)
    packets = []
    while True:
        ok, packet = capture.read()
        if not ok:
            break
        packets.append(packet.tobytes())
    capture.release()
    return packets


def test_a_jpeg_file_cameras_frames_reach_the_client_byte_for_byte(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    server = serve()
    cam = _live(server, f"file://{motion_video}")
    packets = file_packets(motion_video)
    assert len(packets) == LOOP
    with LiveViewer(_url(server)) as viewer:
        # Offered compression, as by a browser, the server declines it: deflating every
        # JPEG again would cost it more than the rest of sending the frame.
        assert viewer.extensions == []
        viewer.watch([cam])
        frames = viewer.wait(cam, 20)
    for _, header, jpeg in frames:
        assert header["camera_id"] == cam and header["size"] == [WIDTH, HEIGHT]
        # The worker's frame n is the file's packet n - 1 (it loops, from the start).
        assert jpeg == packets[(header["frame"] - 1) % LOOP]


def test_an_mjpeg_cameras_frames_reach_the_client_byte_for_byte(
    serve: Callable[..., Running],
) -> None:
    camera = MjpegCamera().start()
    try:
        base = background()
        sent = {cv2.imencode(".jpg", frame_at(i, base))[1].tobytes() for i in range(LOOP)}
        server = serve()
        cam = _live(server, camera.url)
        with LiveViewer(_url(server)) as viewer:
            viewer.watch([cam], width=160)  # Smaller than the camera's: sent as it is all the same.
            frames = viewer.wait(cam, 20)
        assert all(jpeg in sent for _, _, jpeg in frames)
        assert len({jpeg for _, _, jpeg in frames}) > 10
    finally:
        camera.stop()


def test_detections_trails_and_the_mask_come_as_data(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    server = serve()
    cam = _live(server, f"file://{motion_video}", activate=True)
    httpx.patch(f"{server.base}/api/cameras/{cam}", json={"show_mask": True}).raise_for_status()
    with LiveViewer(_url(server)) as viewer:
        viewer.watch([cam])
        # The second crossing: the first may start before detection has learned the scene.
        wait_for(lambda: any(h["frame"] > 2 * LOOP for _, h, _ in viewer.of(cam)), 20, "two loops")
        frames = [f for f in viewer.of(cam) if f[1]["detections"] and f[1]["frame"] > LOOP]
    on_truth = 0
    for _, header, _ in frames:
        truth = square_box((header["frame"] - 1) % LOOP)
        assert truth is not None, "an object where the scene has none"
        tx, ty, tw, th = truth
        for detection in header["detections"]:
            _, y, _, h = detection["box"]
            assert y < ty + th + 8 and ty < y + h + 8, "a box off the square's row"
            assert isinstance(detection["speed_px_s"], float)
        on_truth += any(_iou(d["box"], truth) > 0.5 for d in header["detections"])
        mask = cv2.imdecode(np.frombuffer(base64.b64decode(header["mask"]), np.uint8), -1)
        assert mask.shape == (HEIGHT, WIDTH)  # 320x240: detected at full size.
        assert set(np.unique(mask)) <= {0, 255}
        row = mask[max(0, ty - 10) : ty + th + 10]
        assert mask[ty : ty + th, tx : tx + tw].any() and row.sum() >= 0.9 * mask.sum()
    assert on_truth >= 0.8 * len(frames), f"{on_truth} of {len(frames)} frames boxed the square"
    tracked = [f for f in frames if f[1]["detections"][0]["track_id"] is not None]
    trail = tracked[-1][1]["detections"][0]["trail"]
    xs = [point[0] for point in trail]
    assert xs == sorted(xs) and xs[-1] - xs[0] > 20, "the square moves right"


def test_a_decoded_camera_is_encoded_once_no_wider_than_its_clients_need(
    serve: Callable[..., Running], tmp_path: Path
) -> None:
    """A camera that does not send JPEG (here a folder of PNGs) is encoded once per frame
    for every client, at the widest width a client asked for."""
    folder = tmp_path / "pngs"
    folder.mkdir()
    base = background()
    for index in range(LOOP):
        cv2.imwrite(str(folder / f"{index:03d}.png"), frame_at(index, base))
    server = serve()
    cam = _live(server, str(folder))
    with LiveViewer(_url(server)) as small, LiveViewer(_url(server)) as large:
        small.watch([cam], width=160)
        pictures = small.wait(cam, 5)
        assert {cv2.imdecode(np.frombuffer(j, np.uint8), 1).shape for _, _, j in pictures[-3:]} == {
            (120, 160, 3)
        }
        large.watch([cam], width=240)
        seen = time.monotonic()
        wait_for(
            lambda: len(small.of(cam, seen + 0.5)) >= 10 and len(large.of(cam, seen + 0.5)) >= 10,
            10,
            "frames to both",
        )
        by_frame = {h["frame"]: j for _, h, j in large.of(cam, seen + 0.5)}
        both = [
            (j, by_frame[h["frame"]])
            for _, h, j in small.of(cam, seen + 0.5)
            if h["frame"] in by_frame
        ]
    assert both, "no frame reached both clients"
    for mine, theirs in both:
        assert mine == theirs  # The same bytes: one encode for both.
        assert cv2.imdecode(np.frombuffer(mine, np.uint8), 1).shape == (180, 240, 3)
    assert all(h["size"] == [WIDTH, HEIGHT] for _, h, _ in pictures)


def test_only_watched_cameras_are_sent_and_unwatching_stops_them(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    server = serve()
    first = _live(server, f"file://{motion_video}", name="first")
    second = _live(server, f"file://{motion_video}", name="second")
    with LiveViewer(_url(server)) as viewer:
        viewer.watch([first, 9999])  # An id that is no camera is let be.
        viewer.wait(first, 5)
        assert viewer.of(second) == []
        viewer.watch([second])
        viewer.wait(second, 5)
        time.sleep(0.3)  # A frame already on its way may still come.
        stopped = time.monotonic()
        time.sleep(1.0)
        assert viewer.of(first, stopped) == []
        viewer.watch([])
        time.sleep(0.3)
        stopped = time.monotonic()
        time.sleep(1.0)
        assert viewer.of(second, stopped) == []
        cameras = server.server.config.app.state.services.cameras
        assert cameras.get(first).hub.watching["live"] == 0
        assert cameras.get(second).hub.watching["live"] == 0


def test_a_camera_added_or_given_a_new_source_while_watched_is_followed(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    server = serve()
    first = _live(server, f"file://{motion_video}")
    with LiveViewer(_url(server)) as viewer:
        viewer.watch([first, first + 1])
        viewer.wait(first, 3)
        added = _live(server, f"file://{motion_video}")
        assert added == first + 1
        viewer.wait(added, 3)  # Named before it existed: sent once it does.
        changed = httpx.patch(f"{server.base}/api/cameras/{first}", json={"source": "demo"})
        assert changed.status_code == 200, changed.text
        wait_for(
            lambda: any(h["size"] != [WIDTH, HEIGHT] for _, h, _ in viewer.of(first)),
            20,
            "frames of the new source",
        )


def test_a_client_that_does_not_read_slows_neither_the_camera_nor_another_client(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    server = serve()
    cams = [_live(server, f"file://{motion_video}", name=f"c{i}") for i in range(2)]
    stuck = StuckViewer(_url(server), cams)
    try:
        with LiveViewer(_url(server)) as viewer:
            viewer.watch(cams)
            viewer.wait(cams[0], 5)
            time.sleep(3.0)  # The stuck client's buffers are full long before this.
            start = time.monotonic()
            before = {c: httpx.get(f"{server.base}/api/cameras/{c}").json()["frames"] for c in cams}
            time.sleep(4.0)
            after = {c: httpx.get(f"{server.base}/api/cameras/{c}").json()["frames"] for c in cams}
            seconds = time.monotonic() - start
            for cam in cams:
                read = (after[cam] - before[cam]) / seconds
                shown = len(viewer.of(cam, start)) / seconds
                assert read > 0.85 * FPS, f"camera {cam} read {read:.1f} fps"
                assert shown > 0.85 * FPS, f"camera {cam}: {shown:.1f} fps reached the reader"
        hub = server.server.config.app.state.services.cameras.get(cams[0]).hub
        # The reader has gone; the stuck client is still there, still watching.
        wait_for(lambda: hub.watching["live"] == 1, 5, "the reader to be let go")
    finally:
        stuck.close()


def test_a_bad_watch_message_closes_the_socket_with_the_reason(
    serve: Callable[..., Running],
) -> None:
    server = serve()
    for bad, reason in (
        ("not json", "JSON"),
        ('{"type": "watch", "cameras": "1"}', "cameras"),
        ('{"type": "watch", "cameras": [1.5]}', "integers"),
        ('{"type": "watch", "cameras": [1], "width": -1}', "width"),
        (b"\x00\x01", "binary"),
    ):
        with LiveViewer(_url(server)) as viewer:
            viewer.send('{"type": "hello"}')  # Another type: ignored.
            viewer.send(bad)
            wait_for(lambda viewer=viewer: viewer.closed is not None, 5, "the close")
        assert viewer.closed is not None and viewer.closed.rcvd is not None
        assert viewer.closed.rcvd.code == 1003 and reason in viewer.closed.rcvd.reason, bad


def test_the_annotated_mjpeg_picture_is_made_only_while_an_mjpeg_client_is_open(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    server = serve()
    cam = _live(server, f"file://{motion_video}", activate=True)
    hub = server.server.config.app.state.services.cameras.get(cam).hub
    published: list[Picture] = []
    hub.on_publish = published.append  # The MJPEG viewers' pictures, made in the process.
    with LiveViewer(_url(server)) as viewer:
        viewer.watch([cam])
        viewer.wait(cam, 20)
        assert published == []  # Live frames only: no picture drawn or encoded for them.
        url = f"{server.base}/api/cameras/{cam}/stream.mjpg"
        with httpx.stream("GET", url, timeout=10) as stream:
            chunks = stream.iter_bytes()
            next(chunks)
            wait_for(lambda: len(published) > 5, 10, "pictures with the stream open")
            mark = len(viewer.of(cam))
            viewer.wait(cam, mark + 5)  # The live frames go on beside.
        wait_for(lambda: hub.watching["picture"] == 0, 5, "the stream let go")
        time.sleep(0.3)
        count = len(published)
        time.sleep(1.0)
        assert len(published) == count, "pictures made with no MJPEG client"
    assert all(p.made("picture") for p in published)


PASSWORD = "correct horse"


@pytest.mark.parametrize("guarded", ["session", "origin"])
def test_the_session_and_origin_rules_of_ws_hold(
    serve: Callable[..., Running], guarded: str
) -> None:
    if guarded == "origin":
        server = serve()
        host = server.base.removeprefix("http://")
        assert ws_status(_url(server), origin="http://evil.example") == 403
        assert ws_status(_url(server), additional_headers={"Sec-Fetch-Site": "cross-site"}) == 403
        assert ws_status(_url(server), origin=f"http://{host}") == 101
        return
    server = serve(password=PASSWORD)
    assert ws_status(_url(server)) == 403
    with httpx.Client(base_url=server.base, timeout=10) as client:
        assert client.post("/api/login", json={"password": PASSWORD}).status_code == 200
        cookie = {"Cookie": f"vigil_session={client.cookies['vigil_session']}"}
        created = client.post("/api/cameras", json={"name": "d", "source": "demo"})
        cam_id = created.json()["id"]
        with LiveViewer(_url(server), additional_headers=cookie) as viewer:
            viewer.watch([cam_id])
            viewer.wait(cam_id, 2, timeout=20)
            assert client.post("/api/logout").status_code == 204
            wait_for(lambda: viewer.closed is not None, 10, "the socket to close at logout")
        assert viewer.closed.rcvd is not None and viewer.closed.rcvd.code == 1008
