"""Home Assistant's MQTT discovery: each camera a device of five entities.

Each entity's config is retained at ``<discovery>/<component>/<object id>/config``;
an empty retained payload there removes the entity. The object ids are ``<node>_<id>_
<what>``, ``<node>`` the topic prefix made safe for an id (``vigil`` by default, so the
motion sensor of camera 3 is ``homeassistant/binary_sensor/vigil_3_motion/config``).

- ``binary_sensor`` Motion (``device_class: motion``): ``<p>/cameras/<id>/motion``.
- ``switch`` Detection: Activate (ON) and Stop (OFF) through ``.../active/set``.
- ``number`` Sensitivity, 1..255 through ``.../sensitivity/set``. A camera whose
  sensitivity is automatic publishes ``auto``, the number's ``payload_reset``: Home
  Assistant then shows it unknown rather than a made-up figure.
- ``button`` Automatic sensitivity: sends ``auto`` to ``.../sensitivity/set``.
- ``image`` Snapshot: the latest alarm's JPEG from ``.../snapshot``.

Every entity has ``availability_topic`` ``<p>/status`` and the camera's device block.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from app import __version__
from app.mqtt.topics import AUTO, OFF, OFFLINE, ON, ONLINE, Topics

MANUFACTURER = "Vigil"
MODEL = "Motion-detecting camera"


@dataclass(frozen=True)
class Entity:
    component: str
    what: str
    """The last part of its object id and unique id."""


ENTITIES = (
    Entity("binary_sensor", "motion"),
    Entity("switch", "active"),
    Entity("number", "sensitivity"),
    Entity("button", "sensitivity_auto"),
    Entity("image", "snapshot"),
)


def node_id(prefix: str) -> str:
    """The topic prefix as the first part of an object id (``[a-zA-Z0-9_-]`` only)."""
    return re.sub(r"[^a-zA-Z0-9_-]", "_", prefix)


@dataclass(frozen=True)
class Discovery:
    prefix: str
    """Home Assistant's discovery prefix (``homeassistant``)."""
    topics: Topics

    @property
    def node(self) -> str:
        return node_id(self.topics.prefix)

    def object_id(self, camera_id: int, entity: Entity) -> str:
        return f"{self.node}_{camera_id}_{entity.what}"

    def config_topic(self, camera_id: int, entity: Entity) -> str:
        return f"{self.prefix}/{entity.component}/{self.object_id(camera_id, entity)}/config"

    def configs(self, camera_id: int, name: str) -> dict[str, dict[str, Any]]:
        """Every entity's config for camera ``camera_id`` called ``name``, by its topic."""
        topics = self.topics
        common: dict[str, Any] = {
            "availability_topic": topics.status,
            "payload_available": ONLINE,
            "payload_not_available": OFFLINE,
            "device": {
                "identifiers": [f"{self.node}_{camera_id}"],
                "name": name,
                "manufacturer": MANUFACTURER,
                "model": MODEL,
                "sw_version": __version__,
            },
            "origin": {"name": "Vigil", "sw_version": __version__},
            "qos": 1,
        }
        own: dict[str, dict[str, Any]] = {
            "motion": {
                "name": "Motion",
                "device_class": "motion",
                "state_topic": topics.camera(camera_id, "motion"),
                "payload_on": ON,
                "payload_off": OFF,
            },
            "active": {
                "name": "Detection",
                "icon": "mdi:cctv",
                "state_topic": topics.camera(camera_id, "active"),
                "command_topic": topics.command(camera_id, "active"),
                "payload_on": ON,
                "payload_off": OFF,
                "state_on": ON,
                "state_off": OFF,
            },
            "sensitivity": {
                "name": "Sensitivity",
                "icon": "mdi:tune-variant",
                "entity_category": "config",
                "state_topic": topics.camera(camera_id, "sensitivity"),
                "command_topic": topics.command(camera_id, "sensitivity"),
                "min": 1,
                "max": 255,
                "step": 1,
                "mode": "slider",
                "payload_reset": AUTO,
            },
            "sensitivity_auto": {
                "name": "Automatic sensitivity",
                "icon": "mdi:auto-fix",
                "entity_category": "config",
                "command_topic": topics.command(camera_id, "sensitivity"),
                "payload_press": AUTO,
            },
            "snapshot": {
                "name": "Snapshot",
                "image_topic": topics.camera(camera_id, "snapshot"),
                "content_type": "image/jpeg",
            },
        }
        return {
            self.config_topic(camera_id, entity): {
                **own[entity.what],
                "unique_id": self.object_id(camera_id, entity),
                **common,
            }
            for entity in ENTITIES
        }

    def removals(self, camera_id: int) -> list[str]:
        """The config topics to empty to remove camera ``camera_id``'s entities."""
        return [self.config_topic(camera_id, entity) for entity in ENTITIES]
