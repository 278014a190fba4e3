"""The server's face of a camera in a camera process (``RemoteCamera``), before it reports."""

from __future__ import annotations

from typing import Any

from app.workers.camera_host import CameraProcess, RemoteCamera
from tests.workers.conftest import make_worker


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
