"""A server killed (kill -9) while it records a clip: the clip plays up to where it stopped."""

from __future__ import annotations

import signal
import time
from pathlib import Path

import av
import httpx
import psutil

from app.storage import ClipStore, Database
from app.storage.clips import KILLED, complete_length
from tests.api.vigil_livekit import FPS, WsClient, add_camera, serve_process, write_video

ENV = {"VIGIL_DEMO_CAMERA": "false", "VIGIL_QUIET_S": "0.3", "VIGIL_PRE_ROLL_S": "3"}


def test_kill_9_mid_event_leaves_a_clip_that_plays_to_where_it_stopped(tmp_path: Path) -> None:
    video = write_video(tmp_path / "loop.avi")
    data_dir = tmp_path / "data"
    with serve_process(data_dir, **ENV) as (process, base):
        cam = add_camera(base, f"file://{video}", "door")
        with WsClient(base.replace("http", "ws") + "/ws") as ws:
            httpx.post(f"{base}/api/cameras/{cam}/activate").raise_for_status()
            alarm = ws.wait("alarm", 45, count=2, camera_id=cam)[-1]
            time.sleep(1.2)  # The pre-roll and a second of the event are in the clip.
            # The server and its camera processes die together (a crash, an OOM kill).
            for child in psutil.Process(process.pid).children(recursive=True):
                child.kill()
            process.send_signal(signal.SIGKILL)
            process.wait(10)
            killed_at = time.time()
    event_id = alarm["event_id"]

    db = Database(data_dir / "vigil.db")
    clips = ClipStore(data_dir / "clips")
    try:
        left = db.event(event_id)
        assert left is not None and left["clip_path"] and left["clip_s"] is None, "mid-clip"
        path = clips.path(left["clip_path"])
        assert complete_length(path) > 0, "whole fragments were on disk before the kill"
    finally:
        db.close()

    with serve_process(data_dir, **ENV) as (process, base):
        event = httpx.get(f"{base}/api/events/{event_id}").json()
        assert event["ended_at"] is not None and event["clip_error"] == KILLED
        assert event["clip"] == f"/api/events/{event_id}/clip.mp4"
        clip = httpx.get(base + event["clip"])
        assert clip.status_code == 200 and len(clip.content) == event["clip_bytes"]
        (tmp_path / "kept.mp4").write_bytes(clip.content)
        with av.open(str(tmp_path / "kept.mp4")) as container:
            frames = list(container.decode(video=0))  # To the end, without an error.
        assert abs(len(frames) - event["clip_s"] * FPS) <= 1
        # From the pre-roll to within about a fragment (a second) of the kill.
        assert event["clip_started_at"] <= event["started_at"] - 2.5
        stopped_at = event["clip_started_at"] + event["clip_s"]
        assert event["started_at"] < stopped_at <= killed_at
        assert killed_at - stopped_at < 3.0, (killed_at, stopped_at)
        listed = {e["id"]: e for e in httpx.get(f"{base}/api/events?limit=500").json()}
        assert all(e["clip_s"] is not None for e in listed.values() if e["clip"]), "all finished"
        process.send_signal(signal.SIGTERM)
        assert process.wait(15) in (0, -signal.SIGTERM)
