"""Every sender's /ws message, as a real server sends it, is its model's wire form exactly."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx

from app.events.messages import (
    MESSAGES,
    AnalysisStatus,
    CameraStatus,
    Progress,
    parse_message,
)
from tests.api.vigil_livekit import Running, WsClient, add_camera, wait_for, write_video


def _upload(server: Running, name: str, data: bytes) -> str:
    response = httpx.post(
        f"{server.base}/api/analyses", files={"file": (name, data, "video/x-msvideo")}, timeout=30
    )
    assert response.status_code == 202, response.text
    return str(response.json()["id"])


def test_every_message_a_server_sends_is_one_of_the_models(
    serve: Callable[..., Running], motion_video: Path, tmp_path: Path
) -> None:
    data = tmp_path / "data"
    server = serve(data)
    cam = add_camera(server.base, f"file://{motion_video}", "door")
    blocker = data / "snapshots" / str(cam)  # A file where its folder goes: snapshots fail.
    blocker.parent.mkdir(parents=True, exist_ok=True)
    blocker.write_bytes(b"")
    with WsClient(server.ws) as ws:
        # camera.py: status, alarm (its snapshot refused: a storage_error status), motion_end.
        httpx.post(f"{server.base}/api/cameras/{cam}/activate").raise_for_status()
        ws.wait("alarm", 30, camera_id=cam)
        blocker.unlink()
        saved = wait_for(
            lambda: [a for a in ws.of_type("alarm", camera_id=cam) if a["snapshot_id"]],
            30,
            "an alarm with its snapshot",
        )[0]
        ws.wait("motion_end", 30, camera_id=cam)
        # cameras.py: the status after a PATCH, with the settings it changed.
        patch = {"name": "porch", "sensitivity": 30, "mask": [[[0, 0], [0.2, 0], [0, 0.2]]]}
        httpx.patch(f"{server.base}/api/cameras/{cam}", json=patch).raise_for_status()
        ws.wait("status", 10, camera_id=cam, name="porch")
        # services.py: snapshots_deleted.
        httpx.delete(f"{server.base}/api/snapshots/{saved['snapshot_id']}").raise_for_status()
        ws.wait("snapshots_deleted", 10)
        # analyses.py and analysis.py: queued, running, progress, done; and a failure.
        done = _upload(server, "clip.avi", write_video(tmp_path / "clip.avi", 60).read_bytes())
        failed = _upload(server, "notes.avi", b"not a video at all")
        ws.wait("status", 60, analysis_id=done, status="done")
        ws.wait("status", 60, analysis_id=failed, status="failed")
        received = [{k: v for k, v in m.items() if k != "_received"} for m in ws.messages]

    models = [parse_message(m) for m in received]
    assert [m.wire() for m in models] == received, "each message is its model's wire form"
    assert {type(m) for m in models} == set(MESSAGES)
    assert isinstance(models[0], CameraStatus), "ws.py: where each camera stands, first"
    statuses = [m.wire() for m in models if isinstance(m, CameraStatus)]
    assert any("process" in s for s in statuses), "camera_host: completed by the server"
    assert [s["storage_error"] is None for s in statuses if "storage_error" in s] == [
        False,
        True,
    ]
    patched: dict[str, Any] = next(s for s in statuses if "name" in s)
    assert {k: patched[k] for k in patch} == patch
    analyses = [(m.analysis_id, m.status) for m in models if isinstance(m, AnalysisStatus)]
    assert [s for a, s in analyses if a == done] == ["queued", "running", "done"]
    assert [s for a, s in analyses if a == failed] == ["queued", "running", "failed"]
    progress = [m.wire() for m in models if isinstance(m, Progress) and m.analysis_id == done]
    assert "frames" not in progress[0] and progress[-1]["progress"] == 1
    assert any(p.get("frames") for p in progress), "progress during the analysis"
