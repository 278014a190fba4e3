"""A camera's activity history: the largest moving share of each second while activated."""

from __future__ import annotations

import logging
import math

from app.storage.db import Database

log = logging.getLogger("vigil.activity")

FLUSH_S = 10.0
"""Seconds written to the database together: one commit (one fsync) per camera this often,
not every second. A killed process loses at most this much history."""


class ActivityLog:
    """Fed each detected frame's moving share by the camera's worker thread; writes a row a
    second (``GET /api/cameras/{id}/activity`` reads them)."""

    def __init__(self, camera_id: int, db: Database) -> None:
        self.camera_id = camera_id
        self.db = db
        self._second: int | None = None
        self._largest = 0.0
        self._pending: list[tuple[int, float]] = []
        self._next_flush = 0.0

    def note(self, wall: float, motion: float, mono: float) -> None:
        second = math.floor(wall)
        if second == self._second:
            self._largest = max(self._largest, motion)
            return
        if self._second is not None:
            self._pending.append((self._second, round(self._largest, 6)))
        self._second, self._largest = second, motion
        if mono >= self._next_flush:
            self.flush()
            self._next_flush = mono + FLUSH_S

    def flush(self, finished: bool = False) -> None:
        """Write what is pending; ``finished``: the second under way too (detection stops)."""
        if finished and self._second is not None:
            self._pending.append((self._second, round(self._largest, 6)))
            self._second = None
        if not self._pending:
            return
        pending, self._pending = self._pending, []
        self.db.add_activity(self.camera_id, pending)
