"""The MQTT parts without a broker: topics, payloads, Home Assistant's discovery payloads
and the mirror's publications."""

from __future__ import annotations

import json

import pytest

from app import __version__
from app.mqtt.discovery import ENTITIES, Discovery
from app.mqtt.mirror import CameraInfo, Mirror, Publication, SnapshotRef
from app.mqtt.topics import Topics, parse_on_off, parse_sensitivity, sensitivity_text
from tests.mqtt.home_assistant import problems


def test_topics() -> None:
    topics = Topics("home/vigil")
    assert topics.status == "home/vigil/status"
    assert topics.camera(3, "motion") == "home/vigil/cameras/3/motion"
    assert topics.command(3, "sensitivity") == "home/vigil/cameras/3/sensitivity/set"
    assert topics.parse("home/vigil/cameras/3/active/set") == (3, "active/set")
    assert topics.parse("home/vigil/cameras/12/active") == (12, "active")
    for other in [
        "home/vigil/status",
        "home/vigil/cameras/x/active/set",
        "home/vigil/cameras/03/active/set",
        "home/vigil/cameras/²/active/set",
        "home/vigil/cameras/3",
        "vigil/cameras/3/active/set",
    ]:
        assert topics.parse(other) is None, other
    assert topics.subscriptions() == [
        "home/vigil/cameras/+/active/set",
        "home/vigil/cameras/+/sensitivity/set",
        "home/vigil/cameras/+/active",
    ]


def test_payloads() -> None:
    assert [parse_on_off(p) for p in ("ON", " off\n", "on", "1", "")] == [
        True,
        False,
        True,
        None,
        None,
    ]
    assert parse_sensitivity("40") == 40 and parse_sensitivity(" 12.5 ") == 12.5
    assert parse_sensitivity("AUTO") is None and parse_sensitivity("1") == 1
    for bad in ("0", "256", "-3", "nan", "inf", "abc", "", "40 px"):
        with pytest.raises(ValueError):
            parse_sensitivity(bad)
    assert [sensitivity_text(v) for v in (None, 40, 40.0, 12.5)] == ["auto", "40", "40", "12.5"]


def test_discovery_payloads_carry_what_home_assistant_requires() -> None:
    discovery = Discovery("homeassistant", Topics("vigil"))
    configs = discovery.configs(3, "Front door")
    components = {topic.split("/")[1]: (topic, config) for topic, config in configs.items()}
    assert set(components) == {"binary_sensor", "switch", "number", "button", "image"}
    for component, (topic, config) in components.items():
        assert problems(component, config) == [], (component, problems(component, config))
        assert topic == f"homeassistant/{component}/{config['unique_id']}/config"
        assert config["availability_topic"] == "vigil/status"
        assert config["device"] == {
            "identifiers": ["vigil_3"],
            "name": "Front door",
            "manufacturer": "Vigil",
            "model": "Motion-detecting camera",
            "sw_version": __version__,
        }
    motion_topic, motion = components["binary_sensor"]
    assert motion_topic == "homeassistant/binary_sensor/vigil_3_motion/config"
    assert motion["device_class"] == "motion"
    assert motion["state_topic"] == "vigil/cameras/3/motion"
    assert components["switch"][1]["command_topic"] == "vigil/cameras/3/active/set"
    number = components["number"][1]
    assert (number["min"], number["max"], number["payload_reset"]) == (1, 255, "auto")
    assert components["button"][1]["payload_press"] == "auto"
    image = components["image"][1]
    assert image["image_topic"] == "vigil/cameras/3/snapshot"
    assert image["content_type"] == "image/jpeg"
    unique = [config["unique_id"] for config in configs.values()]
    assert len(set(unique)) == len(ENTITIES)
    # Another prefix, another node: two Vigils on one broker do not share entities.
    other = Discovery("ha", Topics("site/b"))
    assert next(iter(other.configs(3, "x"))) == "ha/binary_sensor/site_b_3_motion/config"


def test_home_assistant_checker_catches_what_it_should() -> None:
    assert "missing state_topic" in problems("binary_sensor", {"unique_id": "u", "device": {}})
    assert any("identifiers" in p for p in problems("switch", {"command_topic": "a", "device": {}}))
    image = {"unique_id": "u", "device": {"identifiers": ["d"]}, "url_topic": "t"}
    assert problems("image", {**image, "content_type": "image/jpeg"})
    assert problems("number", {"command_topic": "c", "min": 5, "max": 5, "unique_id": "u"})
    assert "unknown key stat_topic" in problems("binary_sensor", {"stat_topic": "x"})


def _by_topic(publications: list[Publication]) -> dict[str, object]:
    return {p.topic: p.payload for p in publications}


def test_mirror_follows_cameras_and_events() -> None:
    topics = Topics("vigil")
    mirror = Mirror(topics, Discovery("homeassistant", topics))
    yard = CameraInfo(1, "yard", active=False, sensitivity=None)
    added = _by_topic(mirror.refresh([yard]))
    assert added["vigil/cameras/1/motion"] == "OFF"
    assert added["vigil/cameras/1/active"] == "OFF"
    assert added["vigil/cameras/1/sensitivity"] == "auto"
    assert "homeassistant/image/vigil_1_snapshot/config" in added
    assert mirror.refresh([yard]) == []  # Nothing changed, nothing sent.

    changed = mirror.refresh([CameraInfo(1, "yard", active=True, sensitivity=30)])
    assert _by_topic(changed) == {
        "vigil/cameras/1/active": "ON",
        "vigil/cameras/1/sensitivity": "30",
    }
    renamed = _by_topic(mirror.refresh([CameraInfo(1, "garden", True, 30)]))
    assert set(renamed) == {
        f"homeassistant/{e.component}/vigil_1_{e.what}/config" for e in ENTITIES
    }
    assert all(json.loads(str(p))["device"]["name"] == "garden" for p in renamed.values())

    alarm = {"type": "alarm", "camera_id": 1, "event_id": 7, "snapshot_id": 40, "ts": 1.5}
    first = mirror.alarm(alarm)
    assert [p.topic for p in first] == [
        "vigil/cameras/1/motion",
        "vigil/cameras/1/event",
        "vigil/cameras/1/snapshot",
    ]
    assert first[0].payload == "ON" and first[0].retain
    assert json.loads(str(first[1].payload)) == alarm and not first[1].retain
    assert first[2].payload == SnapshotRef(40)
    again = mirror.alarm({**alarm, "snapshot_id": None})  # A newcomer in the same event.
    assert [p.topic for p in again] == ["vigil/cameras/1/event"]
    assert mirror.alarm({**alarm, "camera_id": 9}) == []  # Unknown camera: nothing.

    end = {"type": "motion_end", "camera_id": 1, "event_id": 7, "ts": 3.0}
    ended = mirror.motion_end(end)
    assert (ended[0].topic, ended[0].payload) == ("vigil/cameras/1/motion", "OFF")
    assert mirror.motion_end(end)[0].topic == "vigil/cameras/1/event"  # Once OFF only.
    assert len(mirror.motion_end(end)) == 1

    everything = _by_topic(mirror.everything())
    assert everything["vigil/status"] == "online"
    assert everything["vigil/cameras/1/motion"] == "OFF"
    assert everything["vigil/cameras/1/snapshot"] == SnapshotRef(40)
    assert _by_topic(mirror.snapshots_deleted([40, 41])) == {"vigil/cameras/1/snapshot": b""}

    mirror.alarm({**alarm, "event_id": 8})
    closing = _by_topic(mirror.closing())
    assert closing == {"vigil/cameras/1/motion": "OFF", "vigil/status": "offline"}

    removed = mirror.refresh([])
    assert all(p.payload == b"" and p.retain for p in removed)
    assert {p.topic for p in removed} >= {
        "homeassistant/binary_sensor/vigil_1_motion/config",
        "vigil/cameras/1/motion",
        "vigil/cameras/1/snapshot",
    }
    assert mirror.motion_end({**end, "event_id": 8}) == []  # Its last words: not published.


def test_mirror_without_discovery_and_seeded_snapshots() -> None:
    mirror = Mirror(Topics("v"), None)
    published = mirror.refresh([CameraInfo(2, "a", True, 12.5), CameraInfo(3, "b", False, None)])
    assert not any(p.topic.startswith("homeassistant") for p in published)
    assert _by_topic(mirror.seed_snapshots({2: 10, 5: 11})) == {
        "v/cameras/2/snapshot": SnapshotRef(10)
    }
    mirror.alarm({"type": "alarm", "camera_id": 2, "event_id": 1, "snapshot_id": 20})
    assert mirror.seed_snapshots({2: 10}) == []  # An older one does not replace a newer.
