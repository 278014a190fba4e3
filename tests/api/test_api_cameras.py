"""Health, the page, camera CRUD, persistence across restarts, the demo camera, passwords
in camera sources."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from app.api.routes.inputs import MAX_MIN_AREA
from app.storage import Database
from tests.api.vigil_livekit import MjpegCamera, Running, WsClient, read_mjpeg_frames, wait_for


def test_health_and_page(serve: Callable[..., Running]) -> None:
    server = serve()
    assert httpx.get(f"{server.base}/api/health").json()["status"] == "ok"
    page = httpx.get(f"{server.base}/")
    assert page.status_code == 200 and "text/html" in page.headers["content-type"]
    assert "Vigil" in page.text
    assert httpx.get(f"{server.base}/static/js/main.js").status_code == 200
    assert httpx.get(f"{server.base}/static/app.css").status_code == 200


def test_demo_camera_on_first_start(serve: Callable[..., Running]) -> None:
    server = serve(demo_camera=True)
    (camera,) = httpx.get(f"{server.base}/api/cameras").json()
    assert camera["name"] == "demo" and camera["source"] == "demo"
    live = wait_for(
        lambda: httpx.get(f"{server.base}/api/cameras/{camera['id']}").json()["state"] == "live",
        10,
        "the demo camera to go live",
    )
    assert live


def test_camera_crud_and_restart(
    serve: Callable[..., Running], motion_video: Path, tmp_path: Path
) -> None:
    data = tmp_path / "data"
    server = serve(data)
    base = server.base
    created = httpx.post(
        f"{base}/api/cameras", json={"name": "yard", "source": f"file://{motion_video}"}
    )
    assert created.status_code == 200
    cam_id = created.json()["id"]
    other = httpx.post(f"{base}/api/cameras", json={"name": "gone", "source": "demo"}).json()["id"]
    bad = httpx.post(f"{base}/api/cameras", json={"name": "x", "source": "ftp://nope"})
    assert bad.status_code == 422 and "unsupported source" in bad.text
    bad_method = httpx.patch(f"{base}/api/cameras/{cam_id}", json={"method": "magic"})
    assert bad_method.status_code == 422
    too_high = httpx.patch(f"{base}/api/cameras/{cam_id}", json={"sensitivity": 300})
    assert too_high.status_code == 422
    misspelt = httpx.patch(f"{base}/api/cameras/{cam_id}", json={"sensitivty": 5})
    assert misspelt.status_code == 422 and "sensitivty" in misspelt.text

    changed = httpx.patch(
        f"{base}/api/cameras/{cam_id}",
        json={"sensitivity": 42, "min_area": 250, "method": "mog2", "name": "back yard"},
    ).json()
    assert (changed["sensitivity"], changed["min_area"], changed["method"], changed["name"]) == (
        42,
        250,
        "mog2",
        "back yard",
    )
    assert httpx.post(f"{base}/api/cameras/{cam_id}/activate").json()["active"] is True
    assert httpx.delete(f"{base}/api/cameras/{other}").status_code == 204
    assert httpx.delete(f"{base}/api/cameras/{other}").status_code == 404
    assert httpx.get(f"{base}/api/cameras/{other}").status_code == 404
    wait_for(
        lambda: httpx.get(f"{base}/api/cameras/{cam_id}").json()["processed"] > 0,
        10,
        "frames processed after Activate",
    )
    server.stop()

    again = serve(data, demo_camera=True)  # A configured camera: no demo is added.
    (camera,) = httpx.get(f"{again.base}/api/cameras").json()
    assert camera["id"] == cam_id and camera["name"] == "back yard"
    assert (camera["sensitivity"], camera["min_area"], camera["method"]) == (42, 250, "mog2")
    assert camera["active"] is True
    wait_for(
        lambda: httpx.get(f"{again.base}/api/cameras/{cam_id}").json()["processed"] > 0,
        10,
        "the restored camera to detect again",
    )
    auto = httpx.patch(f"{again.base}/api/cameras/{cam_id}", json={"sensitivity": None}).json()
    assert auto["sensitivity"] is None
    stopped = httpx.post(f"{again.base}/api/cameras/{cam_id}/stop").json()
    assert stopped["active"] is False


def test_camera_that_cannot_open_shows_error(serve: Callable[..., Running], tmp_path: Path) -> None:
    server = serve()

    def in_error(source: str) -> tuple[int, dict[str, Any]]:
        """Add a camera on ``source``; its id and status once it shows ``error``."""
        added = httpx.post(f"{server.base}/api/cameras", json={"name": "x", "source": source})
        cam = added.json()["id"]
        camera = wait_for(
            lambda: (
                (c := httpx.get(f"{server.base}/api/cameras/{cam}").json())["state"] == "error"
                and c
            ),
            10,
            "the error state",
        )
        return cam, camera

    cam, camera = in_error(str(tmp_path / "absent.avi"))
    assert "file not found" in camera["reason"]
    frame = httpx.get(f"{server.base}/api/cameras/{cam}/frame.jpg", timeout=10)
    assert frame.status_code == 503 and "error" in frame.json()["detail"]
    # A viewer of its stream gets one picture that says so (not a blank that never ends).
    url = f"{server.base}/api/cameras/{cam}/stream.mjpg"
    with httpx.stream("GET", url, timeout=10) as stream:
        (card,) = read_mjpeg_frames(stream.iter_bytes(), 1)
    assert card.shape == (360, 640, 3)
    assert 0.01 < np.mean(card > 128) < 0.2, "light text on a dark card"
    # A folder is a source (of image frames), but this one holds none.
    _, camera = in_error(str(tmp_path))
    assert camera["reason"].startswith(f"no image frames in folder: {tmp_path}")


def test_password_protects_everything_but_health(serve: Callable[..., Running]) -> None:
    server = serve(password="s3cret")
    assert httpx.get(f"{server.base}/api/health").status_code == 200
    assert httpx.get(f"{server.base}/api/cameras").status_code == 401
    assert httpx.get(f"{server.base}/api/cameras", auth=("x", "wrong")).status_code == 401
    assert httpx.get(f"{server.base}/api/cameras", auth=("x", "s3cret")).status_code == 200


def test_ignore_zones_persist_and_bad_ones_are_refused(
    serve: Callable[..., Running], tmp_path: Path
) -> None:
    data = tmp_path / "data"
    server = serve(data)
    cam_id = httpx.post(
        f"{server.base}/api/cameras", json={"name": "garden", "source": "demo"}
    ).json()["id"]
    zone = [[[0.0, 0.0], [0.5, 0.0], [0.5, 1.0], [0.0, 1.0]]]
    changed = httpx.patch(f"{server.base}/api/cameras/{cam_id}", json={"mask": zone})
    assert changed.status_code == 200 and changed.json()["mask"] == zone
    for bad in ([[[0, 0], [1, 0]]], [[[0, 0], [3, 0], [1, 1]]], "left half"):
        refused = httpx.patch(f"{server.base}/api/cameras/{cam_id}", json={"mask": bad})
        assert refused.status_code == 422, bad
    server.stop()
    again = serve(data)
    assert httpx.get(f"{again.base}/api/cameras/{cam_id}").json()["mask"] == zone
    cleared = httpx.patch(f"{again.base}/api/cameras/{cam_id}", json={"mask": None}).json()
    assert cleared["mask"] == []


def test_source_passwords_are_never_shown(serve: Callable[..., Running], tmp_path: Path) -> None:
    """A camera that needs its password: the API, the page and /ws show it masked, the
    worker gets it, and a PATCH that sends the source back as shown keeps it."""
    password = "s3cret-Pw"
    camera = MjpegCamera(auth=("admin", password)).start()
    data = tmp_path / "data"
    server = serve(data)
    base = server.base
    host = f"127.0.0.1:{camera.port}"
    real, shown = (f"http://admin:{p}@{host}/video.mjpg" for p in (password, "***"))

    def stored(cam: int) -> str:
        db = Database(data / "vigil.db")
        try:
            row = db.camera(cam)
            assert row is not None
            return str(row["source"])
        finally:
            db.close()

    def live_again(ws: WsClient, cam: int, before: int) -> None:
        """A status ``live`` for ``cam`` on /ws after the first ``before``: it opened."""
        wait_for(
            lambda: len(ws.of_type("status", camera_id=cam, state="live")) > before,
            15,
            "the camera to open with its password",
        )

    try:
        with WsClient(server.ws) as ws:
            cam = httpx.post(f"{base}/api/cameras", json={"name": "gate", "source": real}).json()
            cam = cam["id"]
            live_again(ws, cam, 0)  # The worker has the real password (401 without).
            listed = httpx.get(f"{base}/api/cameras")
            assert password not in listed.text
            assert [c["source"] for c in listed.json()] == [shown]
            one = httpx.get(f"{base}/api/cameras/{cam}")
            assert one.json()["source"] == shown and password not in one.text
            for path in ("/", "/static/js/main.js"):
                assert password not in httpx.get(f"{base}{path}").text

            # The source sent back as shown, with another setting: the password stays.
            kept = httpx.patch(
                f"{base}/api/cameras/{cam}", json={"source": shown, "sensitivity": 40}
            )
            assert kept.status_code == 200 and password not in kept.text
            assert (kept.json()["source"], kept.json()["sensitivity"]) == (shown, 40)
            assert stored(cam) == real
            # Another path on the same host and user: the stored password goes with it.
            lives = len(ws.of_type("status", camera_id=cam, state="live"))
            moved = httpx.patch(f"{base}/api/cameras/{cam}", json={"source": f"{shown}?s=1"})
            assert moved.json()["source"] == f"{shown}?s=1"
            assert stored(cam) == f"{real}?s=1"
            live_again(ws, cam, lives)  # Started again on the new source, password and all.
            for path in ("/activate", "/stop"):
                answer = httpx.post(f"{base}/api/cameras/{cam}{path}")
                assert answer.status_code == 200 and password not in answer.text

            # The mask sent to another host (or user) is refused: the password stays home.
            for elsewhere in (
                f"http://admin:***@127.0.0.2:{camera.port}/video.mjpg",
                f"http://root:***@{host}/video.mjpg",
            ):
                refused = httpx.patch(f"{base}/api/cameras/{cam}", json={"source": elsewhere})
                assert refused.status_code == 422, refused.text
                assert "type the password" in refused.text and password not in refused.text
            assert stored(cam) == f"{real}?s=1"
            copied = httpx.post(f"{base}/api/cameras", json={"name": "copy", "source": shown})
            assert copied.status_code == 422 and "type the password" in copied.text
            # A refused body never echoes a password: not in the reason, not in the input.
            for body in (
                {"name": "x", "source": f"ftp://admin:{password}@{host}/x"},
                {"name": "x", "source": f"http://admin:{password}@/x"},
                {"source": real},  # No name: the whole body comes back.
            ):
                refused = httpx.post(f"{base}/api/cameras", json=body)
                assert refused.status_code == 422 and password not in refused.text, refused.text
                assert "***" in refused.text

            # A new source replaces it, here with a wrong password: the camera is refused.
            wrong = f"http://admin:wrong-pw@{host}/video.mjpg"
            replaced = httpx.patch(f"{base}/api/cameras/{cam}", json={"source": wrong})
            assert replaced.json()["source"] == shown and stored(cam) == wrong
            ws.wait("status", 15, camera_id=cam, state="error")
            messages = json.dumps(ws.messages)
            assert ws.of_type("status", camera_id=cam) and password not in messages
            assert (
                "wrong-pw" not in messages
                and "wrong-pw" not in httpx.get(f"{base}/api/cameras").text
            )
    finally:
        camera.stop()


def test_camera_settings_take_only_their_own_types_and_sane_values(
    serve: Callable[..., Running],
) -> None:
    """No coercion: a string or a boolean is no sensitivity, "yes" is no boolean; whole
    numbers are numbers. A minimum area larger than any frame would turn detection off."""
    server = serve()
    base = server.base
    cam = httpx.post(f"{base}/api/cameras", json={"name": "door", "source": "demo"}).json()["id"]

    def patched(body: dict[str, Any]) -> httpx.Response:
        return httpx.patch(f"{base}/api/cameras/{cam}", json=body)

    for body in (
        {"sensitivity": "10"},
        {"sensitivity": True},
        {"min_area": "100"},
        {"min_area": False},
        {"show_mask": "yes"},
        {"show_mask": 1},
        {"mask": [[["0", 0], [1, 0], [1, 1]]]},
        {"name": 5},
    ):
        refused = patched(body)
        assert refused.status_code == 422, body
        (error,) = refused.json()["detail"]
        assert error["loc"][:2] == ["body", next(iter(body))], error
        assert error["msg"].startswith("Input should be a valid"), error
    too_large = patched({"min_area": 1e26})
    assert too_large.status_code == 422
    assert f"at most {MAX_MIN_AREA:,}" in too_large.json()["detail"][0]["msg"]
    assert patched({"min_area": MAX_MIN_AREA + 1}).status_code == 422
    assert httpx.get(f"{base}/api/cameras/{cam}").json()["min_area"] == 100

    # What the page sends: numbers (whole or not), booleans, null for automatic.
    for body, shown in (
        ({"sensitivity": 10}, 10),
        ({"sensitivity": 12.5}, 12.5),
        ({"sensitivity": None}, None),
        ({"min_area": MAX_MIN_AREA}, MAX_MIN_AREA),
        ({"min_area": 0}, 0),
        ({"show_mask": True}, True),
    ):
        changed = patched(body)
        assert changed.status_code == 200, changed.text
        assert changed.json()[next(iter(body))] == shown

    for extra in ({"sensitivity": "10"}, {"min_area": 1e26}, {"sensitivity": False}):
        added = httpx.post(f"{base}/api/cameras", json={"name": "x", "source": "demo", **extra})
        assert added.status_code == 422, extra
    added = httpx.post(
        f"{base}/api/cameras", json={"name": "x", "source": "demo", "sensitivity": 20}
    )
    assert added.status_code == 200, added.text


def test_every_body_refuses_unknown_fields(serve: Callable[..., Running]) -> None:
    """As the camera routes do: a misspelt or unknown field is an error, not ignored."""
    server = serve()
    base = server.base
    cam = httpx.post(f"{base}/api/cameras", json={"name": "door", "source": "demo"}).json()["id"]
    for url, body in (
        ("/api/snapshots/delete", {"ids": [1], "all": True}),
        (f"/api/cameras/{cam}/activate", {"camera_id": 2}),
        (f"/api/cameras/{cam}/stop", {"force": True}),
        (f"/api/cameras/{cam}/activate", [1]),
    ):
        refused = httpx.post(f"{base}{url}", json=body)
        assert refused.status_code == 422, (url, body, refused.text)
    assert httpx.get(f"{base}/api/cameras/{cam}").json()["active"] is False
    # Without a body, as the page sends them, or with an empty one, they do their work.
    assert httpx.post(f"{base}/api/cameras/{cam}/activate").json()["active"] is True
    assert httpx.post(f"{base}/api/cameras/{cam}/stop", json={}).json()["active"] is False
    deleted = httpx.post(f"{base}/api/snapshots/delete", json={"ids": [1]})
    assert deleted.status_code == 200 and deleted.json() == {"deleted": []}


def test_a_negative_device_index_is_refused(serve: Callable[..., Running]) -> None:
    server = serve()
    base = server.base
    for source in ("-1", " -3 ", "-0"):
        refused = httpx.post(f"{base}/api/cameras", json={"name": "x", "source": source})
        assert refused.status_code == 422, refused.text
        # Our words, without pydantic's "Value error, " before them (the page shows them).
        assert refused.json()["detail"][0]["msg"].startswith("a device index"), refused.text
    cam = httpx.post(f"{base}/api/cameras", json={"name": "door", "source": "demo"}).json()["id"]
    refused = httpx.patch(f"{base}/api/cameras/{cam}", json={"source": "-1"})
    assert refused.status_code == 422 and "device index" in refused.text
    assert httpx.get(f"{base}/api/cameras").json()[0]["source"] == "demo"
