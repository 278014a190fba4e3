"""Data that outlives the server: kill -9 mid-alarm, a full disk, the size cap on snapshots."""

from __future__ import annotations

import shutil
import signal
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import httpx
import numpy as np
import psutil
import pytest

from app.storage import Database, SnapshotStore
from tests.api.vigil_livekit import (
    Running,
    WsClient,
    add_camera,
    serve_process,
    wait_for,
    write_video,
)


def _decodes(data: bytes) -> bool:
    """A whole JPEG: both markers, and OpenCV reads every row of it."""
    if data[:2] != b"\xff\xd8" or data[-2:] != b"\xff\xd9":
        return False
    return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR) is not None


def test_kill_9_mid_alarm_loses_no_event_and_the_restart_closes_the_open_one(
    tmp_path: Path,
) -> None:
    video = write_video(tmp_path / "loop.avi")
    data_dir = tmp_path / "data"
    with serve_process(data_dir, VIGIL_DEMO_CAMERA="false", VIGIL_QUIET_S="0.3") as (
        process,
        base,
    ):
        cam = add_camera(base, f"file://{video}", "door")
        with WsClient(base.replace("http", "ws") + "/ws") as ws:
            httpx.post(f"{base}/api/cameras/{cam}/activate").raise_for_status()
            ws.wait("alarm", 45, count=3, camera_id=cam)
            # Right after an alarm: its event is open, its rows just written. The server
            # and its camera processes die together, as in a crash or an OOM kill of the
            # service (a camera process that outlives the server ends its events cleanly).
            for child in psutil.Process(process.pid).children(recursive=True):
                child.kill()
            process.send_signal(signal.SIGKILL)
            process.wait(10)
            killed_at = time.time()
            alarms = ws.of_type("alarm", camera_id=cam)
    assert process.returncode == -signal.SIGKILL

    heard_events = {a["event_id"] for a in alarms}
    heard_snapshots = {a["snapshot_id"] for a in alarms} | {
        int(a["difference"].split("/")[-1].removesuffix(".jpg")) for a in alarms
    }
    db = Database(data_dir / "vigil.db")
    store = SnapshotStore(data_dir / "snapshots")
    try:
        events = {e["id"]: e for e in db.events(limit=10_000)}
        assert heard_events <= set(events), "an event announced on /ws is not in the database"
        assert events[alarms[-1]["event_id"]]["ended_at"] is None, "the kill was mid-event"
        snapshots = db.snapshots(limit=10_000)
        assert heard_snapshots <= {s["id"] for s in snapshots}
        for row in snapshots:
            data = store.path(row["path"]).read_bytes()
            assert len(data) == row["size"] and _decodes(data), f"snapshot {row['id']} is broken"
    finally:
        db.close()

    with serve_process(data_dir, VIGIL_DEMO_CAMERA="false", VIGIL_QUIET_S="0.3") as (
        process,
        base,
    ):
        listed = {e["id"]: e for e in httpx.get(f"{base}/api/events?limit=5000").json()}
        assert heard_events <= set(listed)
        for event_id in heard_events:
            event = listed[event_id]
            assert event["ended_at"] is not None, f"event {event_id} was left open"
            assert event["started_at"] <= event["ended_at"] <= killed_at
        for snapshot_id in heard_snapshots:
            picture = httpx.get(f"{base}/api/snapshots/{snapshot_id}.jpg")
            assert picture.status_code == 200 and _decodes(picture.content)
        process.send_signal(signal.SIGTERM)
        # uvicorn re-raises the signal once it has shut down cleanly.
        assert process.wait(15) in (0, -signal.SIGTERM)
        output = process.stdout.read()  # type: ignore[union-attr]
        assert "Traceback" not in output and "ERROR" not in output, output


def _refuse_writes(snapshots: Path, camera_id: int) -> Callable[[], None]:
    """Make snapshot writes fail for real, as root too (a read-only folder does not stop
    root); returns what undoes it."""
    blocker = snapshots / str(camera_id)  # A file where the camera's folder goes.
    shutil.rmtree(blocker, ignore_errors=True)
    blocker.write_bytes(b"")
    return blocker.unlink


def test_a_full_disk_costs_the_pictures_not_the_events_and_snapshots_resume(
    serve: Callable[..., Running],
    motion_video: Path,
    tmp_path: Path,
    capfd: pytest.CaptureFixture[str],
) -> None:
    server = serve(tmp_path / "data")
    cam = add_camera(server.base, f"file://{motion_video}", "door")
    restore = _refuse_writes(tmp_path / "data" / "snapshots", cam)
    with WsClient(server.ws) as ws:
        httpx.post(f"{server.base}/api/cameras/{cam}/activate").raise_for_status()
        failed = ws.wait("alarm", 30, count=2, camera_id=cam)[:2]
        assert all(a["snapshot"] is None and a["snapshot_id"] is None for a in failed)
        health = httpx.get(f"{server.base}/api/health").json()
        assert health["status"] == "ok" and health["storage"]["error"]
        state = httpx.get(f"{server.base}/api/cameras/{cam}").json()
        assert state["state"] == "live", "the camera worker must carry on"

        restore()
        restored = wait_for(
            lambda: [a for a in ws.of_type("alarm", camera_id=cam) if a["snapshot"]],
            30,
            "an alarm with a snapshot after the disk came back",
        )[0]
        reports = [m for m in ws.of_type("status", camera_id=cam) if "storage_error" in m]

    assert [bool(m["storage_error"]) for m in reports] == [True, False], "once per spell"
    assert reports[0]["storage_error"] == health["storage"]["error"]
    # The camera process logs to the server's stderr.
    log_lines = capfd.readouterr().err.splitlines()
    warnings = [line for line in log_lines if "snapshots not saved" in line]
    assert len(warnings) == 1, "a burst of failures is logged once"
    picture = httpx.get(f"{server.base}{restored['snapshot']}")
    assert picture.status_code == 200 and _decodes(picture.content)
    assert httpx.get(f"{server.base}/api/health").json()["storage"]["error"] is None
    events = {e["id"] for e in httpx.get(f"{server.base}/api/events").json()}
    assert {a["event_id"] for a in failed} <= events, "the events stand without pictures"


def _old_snapshots(data_dir: Path, count: int) -> list[tuple[int, int, int]]:
    """``count`` ended events of an hour ago, each with one real JPEG: (event, snapshot, size)."""
    db = Database(data_dir / "vigil.db")
    store = SnapshotStore(data_dir / "snapshots")
    made = []
    start = time.time() - 3600
    for i in range(count):
        pixels = np.random.default_rng(i).integers(0, 256, (96, 96, 3), dtype=np.uint8)
        data = cv2.imencode(".jpg", pixels, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes()
        event = db.add_event(99, start + i, [], 1.0)
        db.end_event(event, start + i + 0.5, 1.0)
        relative = store.save(99, start + i, "frame", data, event)
        snapshot = db.add_snapshot(99, event, start + i, "frame", relative, len(data))
        made.append((event, snapshot, len(data)))
    db.close()
    return made


def test_the_size_cap_holds_at_start_and_while_alarms_add_snapshots(
    serve: Callable[..., Running], motion_video: Path, tmp_path: Path
) -> None:
    data_dir = tmp_path / "data"
    old = _old_snapshots(data_dir, 12)
    cap_bytes = sum(size for _, _, size in old[6:])  # The newest six fit.
    server = serve(data_dir, retention_mb=cap_bytes / 2**20, retention_interval_s=0.2)

    def sizes() -> dict[int, int]:
        return {s["id"]: s["size"] for s in httpx.get(f"{server.base}/api/snapshots").json()}

    wait_for(lambda: set(sizes()) == {s for _, s, _ in old[6:]}, 10, "the oldest six to go")
    events = {e["id"] for e in httpx.get(f"{server.base}/api/events").json()}
    assert events == {e for e, _, _ in old[6:]}, "an ended event goes with its last snapshot"
    storage = httpx.get(f"{server.base}/api/health").json()["storage"]
    assert storage["snapshots_mb"] == round(cap_bytes / 2**20, 3)

    cam = add_camera(server.base, f"file://{motion_video}", "door")
    with WsClient(server.ws) as ws:
        httpx.post(f"{server.base}/api/cameras/{cam}/activate").raise_for_status()
        alarm = ws.wait("alarm", 30, camera_id=cam)[0]
        httpx.post(f"{server.base}/api/cameras/{cam}/stop").raise_for_status()
    assert alarm["snapshot_id"] is not None
    remaining = wait_for(
        lambda: (now := sizes()) and sum(now.values()) <= cap_bytes and now,
        10,
        "the periodic pass to bring the snapshots back under the cap",
    )
    assert old[6][1] not in remaining, "the oldest made room"
    assert alarm["snapshot_id"] in remaining, "the newest snapshot stays"
