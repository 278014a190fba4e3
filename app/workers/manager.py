"""Every camera, spread over the camera processes, started and stopped with the server."""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Iterable
from typing import Any

from app.core.config import Settings
from app.workers.bus import EventBus
from app.workers.camera_host import CameraProcess, RemoteCamera, default_processes


class CameraManager:
    """``loop``: the server's event loop, which reads the camera processes' live frames."""

    def __init__(
        self, settings: Settings, bus: EventBus, loop: asyncio.AbstractEventLoop | None = None
    ) -> None:
        count = settings.camera_processes or default_processes()
        self._processes = [CameraProcess(i, settings, bus, loop) for i in range(count)]
        self._cameras: dict[int, RemoteCamera] = {}
        self._lock = threading.Lock()
        self._changing = threading.RLock()

    def start_all(self, cameras: Iterable[dict[str, Any]]) -> None:
        for camera in cameras:
            self.start(camera)

    def start(self, camera: dict[str, Any], taken_over: bool = False) -> RemoteCamera:
        """Run a camera (again, with its new row, if it runs already) in the least busy process.

        A process starts with its first camera: cameras spread one to a process up to
        the number of processes, and a server with fewer cameras than CPUs does not
        keep idle processes (tens of MB each). ``taken_over``: from a node that died, whose
        open events this one ends first (``motion_end``), as after a camera process's death.
        """
        with self._changing:  # Two PATCHes of one camera must not leave two workers.
            self.remove(camera["id"])
            process = min(self._processes, key=lambda p: (len(p.cameras), not p.started))
            remote = RemoteCamera(camera, process)
            with self._lock:
                self._cameras[camera["id"]] = remote
            process.add(remote, recovering=taken_over)
            return remote

    @property
    def changing(self) -> threading.RLock:
        """Held while cameras start or stop, and while a camera's row and its worker change
        together: one change at a time."""
        return self._changing

    def get(self, camera_id: int) -> RemoteCamera | None:
        with self._lock:
            return self._cameras.get(camera_id)

    def all(self) -> list[RemoteCamera]:
        with self._lock:
            return list(self._cameras.values())

    def remove(self, camera_id: int) -> None:
        with self._changing:
            with self._lock:
                camera = self._cameras.pop(camera_id, None)
            if camera is not None:
                camera.process.remove(camera_id)

    def storage_error(self) -> str | None:
        """Why a camera's snapshots are not being saved, if one's are not."""
        return next((c.storage_error for c in self.all() if c.storage_error), None)

    def stop_all(self, timeout: float) -> bool:
        """Stop every camera process within ``timeout``; True when all stopped cleanly."""
        for process in self._processes:
            process.request_stop()
        deadline = time.monotonic() + timeout
        stopped = [p.wait(max(0.0, deadline - time.monotonic())) for p in self._processes]
        with self._lock:
            self._cameras.clear()
        return all(stopped)
