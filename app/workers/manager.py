"""Every camera's worker, started and stopped together with the server."""

from __future__ import annotations

import threading
import time
from typing import Any

import cv2

from app.core.config import Settings
from app.storage.db import Database
from app.storage.files import SnapshotStore
from app.workers.bus import EventBus
from app.workers.camera import CameraWorker


class CameraManager:
    def __init__(
        self, settings: Settings, db: Database, snapshots: SnapshotStore, bus: EventBus
    ) -> None:
        self.settings = settings
        self.db = db
        self.snapshots = snapshots
        self.bus = bus
        self._workers: dict[int, CameraWorker] = {}
        self._lock = threading.Lock()

    def start_all(self) -> None:
        if self.settings.opencv_threads:
            cv2.setNumThreads(self.settings.opencv_threads)
        for camera in self.db.cameras():
            self.start(camera)

    def start(self, camera: dict[str, Any]) -> CameraWorker:
        worker = CameraWorker(camera, self.settings, self.db, self.snapshots, self.bus)
        with self._lock:
            old = self._workers.get(camera["id"])
            self._workers[camera["id"]] = worker
        if old is not None:
            old.request_stop()
        worker.start()
        return worker

    def restart(self, camera: dict[str, Any]) -> CameraWorker:
        return self.start(camera)

    def get(self, camera_id: int) -> CameraWorker | None:
        with self._lock:
            return self._workers.get(camera_id)

    def all(self) -> list[CameraWorker]:
        with self._lock:
            return list(self._workers.values())

    def remove(self, camera_id: int) -> None:
        with self._lock:
            worker = self._workers.pop(camera_id, None)
        if worker is not None:
            worker.request_stop()

    def stop_all(self, timeout: float = 2.0) -> None:
        """Ask every worker to end, then wait for them together (at most ``timeout``)."""
        workers = self.all()
        for worker in workers:
            worker.request_stop()
        deadline = time.monotonic() + timeout
        for worker in workers:
            worker.join(max(0.0, deadline - time.monotonic()))
        with self._lock:
            self._workers.clear()
