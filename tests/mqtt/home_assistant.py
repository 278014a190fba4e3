"""What Home Assistant's MQTT integration requires of a discovered entity's config, as its
schemas say (homeassistant/components/mqtt: schemas.py, config.py, and each platform's
``PLATFORM_SCHEMA_MODERN``), for the five platforms Vigil uses.

``problems(component, config)`` lists what Home Assistant would refuse, and (stricter than
it, which drops unknown keys silently) any key it does not know, so a misspelt option
shows.
"""

from __future__ import annotations

from typing import Any

COMMON = {
    "availability",
    "availability_mode",
    "availability_template",
    "availability_topic",
    "device",
    "entity_category",
    "enabled_by_default",
    "encoding",
    "icon",
    "json_attributes_template",
    "json_attributes_topic",
    "name",
    "origin",
    "payload_available",
    "payload_not_available",
    "qos",
    "unique_id",
    "default_entity_id",
}
OWN = {
    "binary_sensor": {
        "device_class",
        "expire_after",
        "force_update",
        "off_delay",
        "payload_off",
        "payload_on",
        "state_topic",
        "value_template",
    },
    "switch": {
        "command_template",
        "command_topic",
        "device_class",
        "optimistic",
        "payload_off",
        "payload_on",
        "retain",
        "state_off",
        "state_on",
        "state_topic",
        "value_template",
    },
    "number": {
        "command_template",
        "command_topic",
        "device_class",
        "max",
        "min",
        "mode",
        "optimistic",
        "payload_reset",
        "retain",
        "state_topic",
        "step",
        "unit_of_measurement",
        "value_template",
    },
    "button": {"command_template", "command_topic", "device_class", "payload_press", "retain"},
    "image": {"content_type", "image_encoding", "image_topic", "url_template", "url_topic"},
}
REQUIRED = {
    "binary_sensor": {"state_topic"},
    "switch": {"command_topic"},
    "number": {"command_topic"},
    "button": {"command_topic"},
    "image": set(),
}
DEVICE_KEYS = {
    "configuration_url",
    "connections",
    "hw_version",
    "identifiers",
    "manufacturer",
    "model",
    "name",
    "serial_number",
    "suggested_area",
    "sw_version",
    "via_device",
}
BINARY_SENSOR_CLASSES = {"motion", "occupancy", "presence", "moving"}  # Those that fit here.
ENTITY_CATEGORIES = {"config", "diagnostic"}


def _topic_problems(key: str, value: Any, publish: bool) -> list[str]:
    if not isinstance(value, str) or not value:
        return [f"{key} must be a non-empty string"]
    if "\0" in value or len(value.encode()) > 65535:
        return [f"{key} is not a valid topic"]
    if publish and ("+" in value or "#" in value):
        return [f"{key} is published to: no wildcards"]
    return []


def problems(component: str, config: dict[str, Any]) -> list[str]:
    found: list[str] = []
    allowed = COMMON | OWN[component]
    found += [f"unknown key {key}" for key in config if key not in allowed]
    found += [f"missing {key}" for key in REQUIRED[component] if key not in config]
    for key in ("state_topic", "availability_topic", "image_topic", "url_topic"):
        if key in config:
            found += _topic_problems(key, config[key], publish=False)
    if "command_topic" in config:
        found += _topic_problems("command_topic", config["command_topic"], publish=True)
    if not isinstance(config.get("unique_id"), str) or not config.get("unique_id"):
        found.append("unique_id must be a non-empty string (else no device, no UI settings)")
    device = config.get("device")
    if not isinstance(device, dict):
        found.append("device must be a mapping")
    else:
        found += [f"unknown device key {key}" for key in device if key not in DEVICE_KEYS]
        identifiers = device.get("identifiers")
        if not (identifiers or device.get("connections")):
            found.append("device needs identifiers or connections")
        if identifiers is not None and not (
            isinstance(identifiers, list | str)
            and all(
                isinstance(i, str)
                for i in ([identifiers] if isinstance(identifiers, str) else identifiers)
            )
        ):
            found.append("device identifiers must be strings")
    origin = config.get("origin")
    if origin is not None and not (
        isinstance(origin, dict) and isinstance(origin.get("name"), str)
    ):
        found.append("origin needs a name")
    if config.get("entity_category") not in (None, *ENTITY_CATEGORIES):
        found.append("entity_category must be config or diagnostic")
    if config.get("qos", 0) not in (0, 1, 2):
        found.append("qos must be 0, 1 or 2")
    if (
        component == "binary_sensor"
        and config.get("device_class", "motion") not in BINARY_SENSOR_CLASSES
    ):
        found.append("device_class not one this sensor should have")
    if component == "number":
        low, high = config.get("min", 1), config.get("max", 100)
        if not (isinstance(low, int | float) and isinstance(high, int | float) and low < high):
            found.append("number: min must be less than max")
        if config.get("step", 1) < 0.001:
            found.append("number: step must be at least 0.001")
        if config.get("mode", "auto") not in ("auto", "box", "slider"):
            found.append("number: mode must be auto, box or slider")
    if component == "image":
        sources = [key for key in ("image_topic", "url_topic") if key in config]
        if len(sources) != 1:
            found.append("image: exactly one of image_topic and url_topic")
        if "content_type" in config and "url_topic" in config:
            found.append("image: content_type cannot go with url_topic")
    return found
