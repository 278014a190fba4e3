"""What the routers share: settings, database, snapshot files, workers, the message bus and
the notifier."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import secrets
import shutil
import threading
import time
from pathlib import Path
from typing import Any, cast

from fastapi import HTTPException
from starlette.requests import HTTPConnection

from app.core.config import Settings
from app.events.messages import DELETED_IDS_PER_MESSAGE, CameraStatus, SnapshotsDeleted
from app.mqtt.bridge import MqttBridge
from app.mqtt.broker import Broker
from app.mqtt.mirror import CameraInfo
from app.nodes.keeper import NodeKeeper
from app.nodes.leases import Leases, Node, site
from app.nodes.relay import Relay
from app.notify.notifier import Notifier
from app.sources.live import without_password
from app.storage.clips import ClipStore, finish_unfinished
from app.storage.db import Database
from app.storage.files import SnapshotStore, prune, prune_to_size
from app.vision.motion import DEFAULT_METHOD
from app.workers.analysis import AnalysisLimits, AnalysisManager
from app.workers.bus import EventBus
from app.workers.camera import STATUS_FIELDS
from app.workers.manager import CameraManager

log = logging.getLogger("vigil")

MB = 1024 * 1024


class Services:
    def __init__(self, settings: Settings) -> None:
        self.settings = settings
        self.closing = False
        self.loop: asyncio.AbstractEventLoop | None = None
        """The server's event loop, set before ``start``: it reads the live frames."""
        self.bus = EventBus()
        # Checks VIGIL_NOTIFY_URLS now: a URL Apprise cannot use stops the server's start.
        self.notifier = Notifier(settings)
        self.db: Database | None = None
        self._snapshots: SnapshotStore | None = None
        self._clips: ClipStore | None = None
        self._cameras: CameraManager | None = None
        self.alone = settings.database_url is None
        """Without a shared database this node is alone: it runs every camera, as always.
        With one, it runs those it leases (``keeper``)."""
        self.keeper: NodeKeeper | None = None
        self.relay_token = secrets.token_urlsafe(32)
        """What the site's other nodes show this one to be relayed its pictures and files."""
        self.relay: Relay | None = None
        """Asks the other nodes for what they hold (with a shared database)."""
        self._analyses: AnalysisManager | None = None
        self._stopping = threading.Event()
        self._pruner: threading.Thread | None = None
        self.mqtt: MqttBridge | None = None
        """The MQTT bridge, with ``VIGIL_MQTT_URL``; run by the app's lifespan."""
        if settings.mqtt_url:
            self.mqtt = MqttBridge(
                Broker.parse(settings.mqtt_url),
                settings.mqtt_prefix,
                settings.mqtt_discovery_prefix,
                MqttControl(self),
                settings.mqtt_reconnect_max_s,
                node=None if self.alone else settings.node,
            )

    @property
    def database(self) -> Database:
        if self.db is None:
            raise RuntimeError("the server has not started")
        return self.db

    @property
    def snapshots(self) -> SnapshotStore:
        assert self._snapshots is not None
        return self._snapshots

    @property
    def clips(self) -> ClipStore:
        assert self._clips is not None
        return self._clips

    @property
    def cameras(self) -> CameraManager:
        assert self._cameras is not None
        return self._cameras

    @property
    def analyses(self) -> AnalysisManager:
        assert self._analyses is not None
        return self._analyses

    def start(self) -> None:
        settings = self.settings
        settings.data_dir.mkdir(parents=True, exist_ok=True)
        # Migrated first, before any camera process.
        self.db = Database(settings.database, node=settings.node)
        log.info("database: %s, %s", self.db.dialect, self.db.shown)
        if self.alone:  # No worker runs yet: the last run's. (Nodes end them on taking over.)
            closed = len(self.db.close_open_events())
            if closed:
                log.info("closed %d event(s) left open when the server last stopped", closed)
        self._snapshots = SnapshotStore(
            settings.snapshots_dir, on_deleted=self.announce_deleted_snapshots
        )
        self._clips = ClipStore(settings.clips_dir)
        finish_unfinished(self.db, self._clips)  # Clips the last run was recording.
        # Before the cameras: the first alarm finds every target ready.
        self.notifier.start(self.db, self._snapshots)
        self._cameras = CameraManager(settings, self.bus, self.loop)
        self._analyses = AnalysisManager(
            self.db,
            self.bus,
            settings.analyses_dir,
            settings.analysis_workers,
            settings.analysis_timeout_s,
            AnalysisLimits(settings.max_upload_pixels, settings.analysis_memory_mb or None),
        )
        demo = ("demo", "demo", DEFAULT_METHOD, settings.default_min_area)
        if settings.demo_camera and self.db.add_first_camera(*demo) is not None:
            log.info("no camera configured: added the demo camera")
        if self.alone:
            self._cameras.start_all(self.db.cameras())
        else:
            node = Node(
                settings.node, settings.node_address, settings.node_capacity, self.relay_token
            )
            self.relay = Relay(self.db, node.name, self.relay_token, settings.lease_s)
            leases = Leases(self.db, node, settings.lease_s)
            self.keeper = NodeKeeper(leases, self.db, self._cameras, also=self._follow_site)
            self.keeper.start()
            log.info("node %s of the site: runs up to %d cameras", node.name, node.capacity)
        self._analyses.start()
        if settings.retention_days > 0 or settings.retention_mb > 0:
            self._pruner = threading.Thread(
                target=self._prune_forever, name="retention", daemon=True
            )
            self._pruner.start()

    def _follow_site(self) -> None:
        """At each renewal: the notification targets another node's API changed, and the
        files of this node whose rows another node deleted."""
        self.notifier.follow_targets()
        for kind, path in self.database.take_file_deletions():
            with contextlib.suppress(ValueError):  # A path outside the folder: none of ours.
                (self.snapshots if kind == "snapshot" else self.clips).delete(path)

    def _prune_forever(self) -> None:
        """Apply ``retention_days`` and ``retention_mb`` now, then every ``retention_interval_s``.

        Cheap enough to run often: both start from an index or the running total.
        """
        settings = self.settings
        while not self._stopping.is_set():
            try:
                if settings.retention_days > 0:
                    before = time.time() - settings.retention_days * 86400
                    removed = prune(self.database, self.snapshots, before, clips=self.clips)
                    if removed:
                        log.info("retention: removed %d old snapshots and clips", removed)
                if settings.retention_mb > 0:
                    cap = int(settings.retention_mb * MB)
                    removed = prune_to_size(self.database, self.snapshots, cap, clips=self.clips)
                    if removed:
                        log.info(
                            "retention: removed %d snapshots and clips to stay under %g MB",
                            removed,
                            settings.retention_mb,
                        )
            except Exception:
                log.exception("retention pass failed")
            self._stopping.wait(settings.retention_interval_s)

    def announce_deleted_snapshots(self, ids: list[int]) -> None:
        """Tell every page (``snapshots_deleted`` on /ws) which snapshots have just been
        deleted, so none keeps showing one its browser already loaded."""
        for start in range(0, len(ids), DELETED_IDS_PER_MESSAGE):
            chunk = ids[start : start + DELETED_IDS_PER_MESSAGE]
            self.bus.publish(SnapshotsDeleted(ids=chunk))

    def mqtt_health(self) -> dict[str, Any]:
        """``disabled`` without ``VIGIL_MQTT_URL``; else ``connected`` or ``disconnected``
        (with the reason), the broker and since when."""
        return {"state": "disabled"} if self.mqtt is None else self.mqtt.health()

    def database_health(self) -> dict[str, Any]:
        """Which database: ``{"engine": "sqlite"}`` or ``{"engine": "postgresql"}`` (no
        address: /api/health answers without a password)."""
        return {"engine": self.database.dialect}

    def nodes(self) -> list[dict[str, Any]]:
        """The site's nodes (``GET /api/nodes``): from the database, or this one alone."""
        settings = self.settings
        if not self.alone:
            return site(self.database, settings.lease_s)
        running = sorted(camera.camera_id for camera in self.cameras.all())
        return [
            {
                "name": settings.node,
                "url": settings.node_address,
                "cameras": running,
                "renewed_at": time.time(),
                "load": len(running) / settings.node_capacity,
                "capacity": settings.node_capacity,
                "alive": True,
            }
        ]

    def node_of(self, camera_id: int) -> str | None:
        """The other node that runs the camera (as this node's last renewal read it); None
        when it runs here or there is no other node. 404 for no such camera; 503 for one
        that runs on no node now (its node is gone, or it is pinned to one not running)."""
        if self.cameras.get(camera_id) is not None or self.keeper is None:
            return None
        placement = self.keeper.placement
        if camera_id not in placement:
            raise HTTPException(404, f"no camera {camera_id}")
        node = placement[camera_id]
        if node is None or node == self.settings.node:
            raise HTTPException(503, f"camera {camera_id} is not running on any node now")
        return node

    def holder(self, row: dict[str, Any], path: Path) -> str | None:
        """The other node to ask for a file (a snapshot's or a clip's, of ``row``) that is
        not here at ``path``: the node that made it. None: ask none (it is here, or was
        made by this node or before there were nodes)."""
        node = row.get("node")
        if self.alone or path.is_file() or node in (None, self.settings.node):
            return None
        return str(node)

    def storage(self) -> dict[str, Any]:
        """Free space, the snapshots' and clips' totals and cap, and why snapshots or clips
        fail (None: they don't)."""
        try:
            free_mb: float | None = round(shutil.disk_usage(self.settings.media).free / MB, 1)
        except OSError:
            free_mb = None
        return {
            "free_mb": free_mb,
            "snapshots_mb": round(self.database.snapshot_bytes() / MB, 3),
            "clips_mb": round(self.database.clip_bytes() / MB, 3),
            "cap_mb": self.settings.retention_mb or None,
            "error": self.cameras.storage_error(),
        }

    def end_streams(self) -> None:
        """The server is stopping: every stream ends now (workers stop later, in stop())."""
        self.closing = True
        if self._cameras is not None:
            for worker in self._cameras.all():
                worker.hub.close()

    def stop(self) -> None:
        self.closing = True
        self._stopping.set()
        self.bus.close()
        if self._analyses is not None:
            self._analyses.stop(timeout=2.0)
        if self.keeper is not None:
            self.keeper.stop()
        if self._cameras is not None:
            # A worker blocked in a network read returns within the read timeout.
            self._cameras.stop_all(timeout=self.settings.read_timeout_ms / 1000 + 2.0)
        if self.keeper is not None:  # Its cameras' events ended: the others may take them.
            self.keeper.leave()
        self.notifier.stop()
        if self.db is not None:
            self.db.close()

    def add_camera(self, camera: dict[str, Any]) -> None:
        """A camera just added to the database: run it here, or (nodes) let the leases
        place it, at once."""
        if self.keeper is None:
            self.cameras.start(camera)
        else:
            self.keeper.wake()

    def delete_camera(self, camera_id: int) -> None:
        with self.cameras.changing:  # Not started again meanwhile by a renewal.
            self.cameras.remove(camera_id)
            self.database.delete_camera(camera_id)

    def set_active(self, camera_id: int, active: bool) -> dict[str, Any] | None:
        """Activate or Stop a camera (``POST /api/cameras/{id}/activate|stop``, MQTT's
        ``active/set``); the camera as the API shows it, None when there is none. On
        another node, its worker follows the row at that node's next renewal."""
        with self.cameras.changing:
            camera = self.database.update_camera(camera_id, active=int(active))
            if camera is None:
                return None
            worker = self.cameras.get(camera_id)
            if worker is not None:
                worker.set_active(active)  # Its status (on /ws) follows at once.
        return self.camera_view(camera)

    def change_camera(
        self, camera_id: int, before: dict[str, Any], changes: dict[str, Any]
    ) -> dict[str, Any] | None:
        """Apply checked ``changes`` to a camera whose row was ``before`` (``PATCH
        /api/cameras/{id}``, MQTT's ``sensitivity/set``): stored, given to its worker (a new
        worker for a new source), and told to every page. The camera as the API shows it;
        None when there is none."""
        with self.cameras.changing:
            camera = self.database.update_camera(camera_id, **changes)
            if camera is None:
                return None
            worker = self.cameras.get(camera_id)
            if worker is not None and changes.get("source", before["source"]) == before["source"]:
                worker.update(**changes)
            elif worker is not None or self.keeper is None:
                self.cameras.start(camera)
        if self.keeper is not None:  # Its node (this one, or another at its next renewal)
            self.keeper.wake()  # follows the row; a new pin moves it.
        view = self.camera_view(camera)
        # Every page shows the change at once, not at its next listing of the cameras; of a
        # camera no node runs now (or whose node did not answer), at that listing.
        status = {key: view[key] for key in STATUS_FIELDS if key in view}
        if status.keys() == set(STATUS_FIELDS) - {"camera_id"}:
            changed = {key: view[key] for key in changes}
            self.bus.publish(CameraStatus(**{"camera_id": camera_id, **status, **changed}))
        return view

    def camera_view(self, camera: dict[str, Any], ask_others: bool = True) -> dict[str, Any]:
        """A camera as the API shows it: its settings (the source ``without_password``), its
        live state and its URLs. The state of a camera another node runs is that node's
        (``ask_others``: asked of it; else only said to run there)."""
        worker = self.cameras.get(camera["id"])
        node = self.settings.node if self.alone else camera["node"]
        remote = None
        if worker is None and node not in (None, self.settings.node) and ask_others:
            remote = self.relay.statuses(node).get(camera["id"]) if self.relay else None
        if worker is not None:
            status = worker.status()
        elif node is None or node == self.settings.node:
            status = {"state": "stopped", "reason": "", "fps": 0.0}
        elif remote is not None:
            status = {key: remote[key] for key in STATUS_FIELDS if key in remote}
        else:
            status = {"state": "stopped", "reason": f"runs on node {node}", "fps": 0.0}
        status.pop("camera_id", None)
        base = f"/api/cameras/{camera['id']}"
        return {
            **camera,
            **status,
            "source": without_password(camera["source"]),
            "active": camera["active"],
            "node": node,
            "stream": f"{base}/stream.mjpg",
            "histogram": f"{base}/histogram.mjpg",
            "frame": f"{base}/frame.jpg",
        }


class MqttControl:
    """What the MQTT bridge reads and does (``app.mqtt.bridge.Control``), through the same
    methods as the API."""

    def __init__(self, services: Services) -> None:
        self.services = services

    def cameras(self) -> list[CameraInfo]:
        return [
            CameraInfo(
                camera_id=camera.camera_id,
                name=str(camera.row["name"]),
                active=bool(camera.row.get("active")),
                sensitivity=camera.row.get("sensitivity"),
            )
            for camera in self.services.cameras.all()
        ]

    def set_active(self, camera_id: int, active: bool) -> bool:
        return self.services.set_active(camera_id, active) is not None

    def set_sensitivity(self, camera_id: int, sensitivity: float | None) -> bool:
        svc = self.services
        before = svc.database.camera(camera_id)
        changes = {"sensitivity": sensitivity}
        return before is not None and svc.change_camera(camera_id, before, changes) is not None

    def snapshot_jpeg(self, snapshot_id: int) -> bytes | None:
        svc = self.services
        row = svc.database.snapshot(snapshot_id)
        if row is None:
            return None
        try:
            return svc.snapshots.path(row["path"]).read_bytes()
        except (OSError, ValueError):  # Deleted meanwhile; a path outside the folder.
            return None

    def elsewhere(self) -> frozenset[int]:
        keeper = self.services.keeper
        if keeper is None:  # Alone: every camera runs here.
            return frozenset()
        return keeper.site - {camera.camera_id for camera in self.services.cameras.all()}

    def latest_snapshots(self, camera_ids: list[int]) -> dict[int, int]:
        latest = {}
        for camera_id in camera_ids:
            rows = self.services.database.snapshots(camera_id=camera_id, kind="frame", limit=1)
            if rows:
                latest[camera_id] = int(rows[0]["id"])
        return latest


def services(request: HTTPConnection) -> Services:
    return cast(Services, request.app.state.services)
