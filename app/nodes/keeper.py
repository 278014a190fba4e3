"""This node runs exactly the cameras it leases (``app.nodes.leases``).

A thread renews the leases every ``lease_s / 3`` seconds (and at once when woken: a camera
added or changed here). After each renewal the cameras gained start, each ending first
the events its dead node left open (``motion_end``, as after a restart); the cameras lost
stop; and those kept follow their rows: activation, sensitivity, zones and the rest,
changed on another node, reach their worker here within one renewal.

While the database cannot be reached the cameras go on; once this node's leases have run
out by its own clock, it stops them all, for the others may have taken them over.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from app.nodes.leases import Leases
from app.storage.db import Database
from app.workers.camera import SETTING_FIELDS
from app.workers.manager import CameraManager

log = logging.getLogger("vigil.nodes")

FOLLOWED = ("name", "source", "active", *SETTING_FIELDS)
"""What a running camera takes from its row at each renewal."""
STOP_WAIT_S = 10.0


class NodeKeeper:
    def __init__(
        self,
        leases: Leases,
        db: Database,
        cameras: CameraManager,
        also: Callable[[], None] = lambda: None,
    ) -> None:
        """``also``: what else follows the database at each renewal."""
        self.leases = leases
        self.db = db
        self.cameras = cameras
        self.also = also
        self._wake = threading.Event()
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name="leases", daemon=True)
        self.site: frozenset[int] = frozenset()
        """Every camera of the site, as the last renewal read them."""
        self.placement: dict[int, str | None] = {}
        """Each camera of the site and the node that holds it, as the last renewal read them."""

    def start(self) -> None:
        """Renew once now (the server answers with its cameras running), then every period."""
        self.renew()
        self._thread.start()

    def wake(self) -> None:
        """Renew now: a camera was added or changed."""
        self._wake.set()

    def stop(self) -> None:
        """Renew no more (the server is stopping; ``leave`` once its cameras have stopped)."""
        self._stopping.set()
        self._wake.set()
        if self._thread.is_alive():
            self._thread.join(STOP_WAIT_S)

    def leave(self) -> None:
        try:
            self.leases.leave()
        except Exception:  # Its leases run out instead.
            log.exception("could not give up the leases")

    def renew(self) -> None:
        held = set(self.leases.renew())
        with self.cameras.changing:  # Not while the API changes a row and its worker.
            every = self.db.cameras()
            self.site = frozenset(r["id"] for r in every)
            self.placement = {r["id"]: r["node"] for r in every}
            self._place({r["id"]: r for r in every if r["id"] in held})
        self.also()

    def _run(self) -> None:
        renewed = time.monotonic()
        failing = False
        while True:
            self._wake.wait(self.leases.period_s)
            self._wake.clear()
            if self._stopping.is_set():
                return
            started = time.monotonic()  # The lease runs from no later than this.
            try:
                self.renew()
            except Exception:
                if not failing:  # Once per outage, not at every renewal.
                    log.warning("cannot renew the leases: retrying", exc_info=True)
                failing = True
                if time.monotonic() - renewed > self.leases.lease_s and self.cameras.all():
                    log.error("the leases have run out: stopping every camera of this node")
                    with self.cameras.changing:
                        self._place({})
                continue
            if failing:
                log.info("leases renewed again")
            renewed, failing = started, False

    def _place(self, rows: dict[int, dict[str, Any]]) -> None:
        for running in self.cameras.all():
            if running.camera_id not in rows:
                log.info("camera %s: no longer leased here, stopped", running.camera_id)
                self.cameras.remove(running.camera_id)
        for camera_id, row in rows.items():
            worker = self.cameras.get(camera_id)
            if worker is None:
                log.info("camera %s: leased here, started", camera_id)
                self.cameras.start(row, taken_over=True)
                continue
            changes = {k: row[k] for k in FOLLOWED if worker.row.get(k) != row[k]}
            if "source" in changes:
                self.cameras.start(row)
                continue
            if "active" in changes:
                worker.set_active(changes.pop("active"))
            if changes:
                worker.update(**changes)
