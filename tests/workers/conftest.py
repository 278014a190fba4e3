"""A camera worker's parts on real files: settings, SQLite database, snapshot folder, bus."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from app.storage import Database, SnapshotStore
from app.vision.motion import DEFAULT_METHOD
from app.workers.bus import EventBus
from app.workers.camera import CameraWorker
from tests.api.vigil_livekit import live_settings


@pytest.fixture
def parts(tmp_path: Path) -> dict[str, Any]:
    return worker_parts(tmp_path)


def worker_parts(tmp_path: Path, **overrides: Any) -> dict[str, Any]:
    settings = live_settings(tmp_path / "data", **overrides)
    db = Database(settings.db_path)
    return {
        "settings": settings,
        "db": db,
        "snapshots": SnapshotStore(settings.snapshots_dir),
        "bus": EventBus(),
    }


def make_worker(parts: dict[str, Any], source: str, **camera: Any) -> CameraWorker:
    db: Database = parts["db"]
    cam_id = db.add_camera("cam", source, DEFAULT_METHOD, 100.0, camera.get("sensitivity"))
    row = db.camera(cam_id)
    assert row is not None
    row.update(camera)
    return CameraWorker(row, parts["settings"], db, parts["snapshots"], parts["bus"])
