"""What the broker should hold, and the publications that keep it so.

The mirror follows the server's event bus (``alarm``, ``motion_end``, ``status``,
``snapshots_deleted``) and the cameras' own state (name, Activate, sensitivity). It never
waits: each change gives the publications it needs, which the bridge sends when a broker
is connected. After a reconnect, ``everything()`` is what the cameras are now (motion
from the events open now, not a replay of what was missed).
"""

from __future__ import annotations

import json
from collections.abc import Container, Iterable
from dataclasses import dataclass, field
from typing import Any

from app.mqtt.discovery import Discovery
from app.mqtt.topics import OFFLINE, ONLINE, STATES, Topics, on_off, sensitivity_text


@dataclass(frozen=True)
class CameraInfo:
    """A camera as the server runs it now."""

    camera_id: int
    name: str
    active: bool
    sensitivity: float | None


@dataclass(frozen=True)
class SnapshotRef:
    """A snapshot's JPEG, read from disk only when it is about to be sent."""

    snapshot_id: int


Payload = str | bytes | SnapshotRef


@dataclass(frozen=True)
class Publication:
    topic: str
    payload: Payload
    retain: bool = True


@dataclass
class CameraMirror:
    info: CameraInfo
    open_events: set[int] = field(default_factory=set)
    """The camera's events that started (``alarm``) and have not ended (``motion_end``)."""
    snapshot_id: int | None = None
    """The latest alarm's snapshot."""

    @property
    def motion(self) -> bool:
        return bool(self.open_events)


class Mirror:
    def __init__(self, topics: Topics, discovery: Discovery | None) -> None:
        self.topics = topics
        self.discovery = discovery
        self.cameras: dict[int, CameraMirror] = {}

    # The cameras ----------------------------------------------------------------------------

    def refresh(
        self, cameras: Iterable[CameraInfo], elsewhere: Container[int] = ()
    ) -> list[Publication]:
        """Follow the cameras as they are now: added, removed, renamed, activated or
        stopped, their sensitivity changed. One gone ``elsewhere`` (to another node, which
        publishes it now) is forgotten, not removed."""
        current = {info.camera_id: info for info in cameras}
        out: list[Publication] = []
        for camera_id in sorted(self.cameras.keys() - current.keys()):
            del self.cameras[camera_id]
            if camera_id not in elsewhere:
                out += self.removal(camera_id)
        for camera_id, info in current.items():
            mirror = self.cameras.get(camera_id)
            if mirror is None:
                mirror = self.cameras[camera_id] = CameraMirror(info)
                out += self.camera_state(mirror)
                continue
            before, mirror.info = mirror.info, info
            if info.name != before.name:
                out += self.configs(info)
            if info.active != before.active:
                out.append(self._state(camera_id, "active", on_off(info.active)))
            if info.sensitivity != before.sensitivity:
                text = sensitivity_text(info.sensitivity)
                out.append(self._state(camera_id, "sensitivity", text))
        return out

    def seed_snapshots(self, latest: dict[int, int]) -> list[Publication]:
        """The latest snapshot of each camera from before this start (from the database)."""
        out: list[Publication] = []
        for camera_id, snapshot_id in latest.items():
            mirror = self.cameras.get(camera_id)
            if mirror is not None and (mirror.snapshot_id or 0) < snapshot_id:
                mirror.snapshot_id = snapshot_id
                out.append(self._state(camera_id, "snapshot", SnapshotRef(snapshot_id)))
        return out

    # The bus ------------------------------------------------------------------------------

    def alarm(self, message: dict[str, Any]) -> list[Publication]:
        """An ``alarm``: motion ON first (the figure to be fast), then the event's JSON and
        the snapshot."""
        mirror = self.cameras.get(message["camera_id"])
        if mirror is None:
            return []
        out: list[Publication] = []
        camera_id = mirror.info.camera_id
        if not mirror.motion:
            out.append(self._state(camera_id, "motion", on_off(True)))
        mirror.open_events.add(message["event_id"])
        out.append(self._event(camera_id, message))
        snapshot_id = message.get("snapshot_id")
        if isinstance(snapshot_id, int):
            mirror.snapshot_id = snapshot_id
            out.append(self._state(camera_id, "snapshot", SnapshotRef(snapshot_id)))
        return out

    def motion_end(self, message: dict[str, Any]) -> list[Publication]:
        mirror = self.cameras.get(message["camera_id"])
        if mirror is None:
            return []
        camera_id = mirror.info.camera_id
        was_moving = mirror.motion
        mirror.open_events.discard(message["event_id"])
        out = [self._event(camera_id, message)]
        if was_moving and not mirror.motion:
            out.insert(0, self._state(camera_id, "motion", on_off(False)))
        return out

    def snapshots_deleted(self, ids: Iterable[int]) -> list[Publication]:
        """A camera's latest snapshot deleted (by a user, or retention) leaves the broker
        too: the retained picture is cleared."""
        gone = set(ids)
        out: list[Publication] = []
        for mirror in self.cameras.values():
            if mirror.snapshot_id in gone:
                mirror.snapshot_id = None
                out.append(self._state(mirror.info.camera_id, "snapshot", b""))
        return out

    # Whole states -------------------------------------------------------------------------

    def everything(self) -> list[Publication]:
        """All the broker should hold, as things are now: after every (re)connect."""
        out = [Publication(self.topics.status, ONLINE)]
        for mirror in self.cameras.values():
            out += self.camera_state(mirror)
        return out

    def closing(self) -> list[Publication]:
        """The server is stopping: its events end with it, then it is offline."""
        out = [
            self._state(mirror.info.camera_id, "motion", on_off(False))
            for mirror in self.cameras.values()
            if mirror.motion
        ]
        return [*out, Publication(self.topics.status, OFFLINE)]

    def camera_state(self, mirror: CameraMirror) -> list[Publication]:
        info = mirror.info
        camera_id = info.camera_id
        out = self.configs(info)
        out.append(self._state(camera_id, "motion", on_off(mirror.motion)))
        out.append(self._state(camera_id, "active", on_off(info.active)))
        out.append(self._state(camera_id, "sensitivity", sensitivity_text(info.sensitivity)))
        if mirror.snapshot_id is not None:
            out.append(self._state(camera_id, "snapshot", SnapshotRef(mirror.snapshot_id)))
        return out

    def configs(self, info: CameraInfo) -> list[Publication]:
        if self.discovery is None:
            return []
        configs = self.discovery.configs(info.camera_id, info.name)
        return [Publication(topic, _json(config)) for topic, config in configs.items()]

    def removal(self, camera_id: int) -> list[Publication]:
        """A camera gone: its entities removed, its retained states cleared."""
        topics = self.discovery.removals(camera_id) if self.discovery is not None else []
        topics += [self.topics.camera(camera_id, name) for name in STATES]
        return [Publication(topic, b"") for topic in topics]

    def _state(self, camera_id: int, name: str, payload: Payload) -> Publication:
        return Publication(self.topics.camera(camera_id, name), payload)

    def _event(self, camera_id: int, message: dict[str, Any]) -> Publication:
        return Publication(self.topics.camera(camera_id, "event"), _json(message), retain=False)


def _json(value: Any) -> str:
    return json.dumps(value, separators=(",", ":"), ensure_ascii=False)
