"""MQTT and Home Assistant against a real Mosquitto and a real uvicorn: the states, events
and snapshots on the broker, the commands, discovery, the will and the clean stop."""

from __future__ import annotations

import json
import logging
import os
import signal
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import cv2
import httpx
import numpy as np
import pytest

from app import __version__
from tests.api.vigil_livekit import (
    Running,
    WsClient,
    add_camera,
    serve_process,
    wait_for,
)
from tests.mqtt.home_assistant import problems
from tests.mqtt.mosquitto import Mosquitto, Watcher, mqtt_settings, retained

Serve = Callable[..., Running]
Broker = Callable[..., Mosquitto]
COMPONENTS = ("binary_sensor", "switch", "number", "button", "image")


@contextmanager
def _watched(
    serve: Serve, mosquitto: Broker, prefix: str = "vigil", **settings: Any
) -> Iterator[tuple[Mosquitto, Watcher, Running]]:
    """A broker, a client watching all of it, and a Vigil on it that has said it is online."""
    broker = mosquitto()
    with Watcher(broker.port) as watcher:
        server = serve(**mqtt_settings(broker, mqtt_prefix=prefix, **settings))
        watcher.wait(f"{prefix}/status", "online")
        yield broker, watcher, server


def _ws_fields(message: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in message.items() if k != "_received"}


def _camera(server: Running, camera_id: int) -> dict[str, Any]:
    answer = httpx.get(f"{server.base}/api/cameras/{camera_id}")
    answer.raise_for_status()
    return dict(answer.json())


def test_health_says_mqtt_is_disabled_without_a_broker(serve: Serve) -> None:
    server = serve()
    assert httpx.get(f"{server.base}/api/health").json()["mqtt"] == {"state": "disabled"}


def test_a_cameras_motion_event_and_snapshot_reach_the_broker_as_on_ws(
    serve: Serve, mosquitto: Broker, motion_video: Path
) -> None:
    with _watched(serve, mosquitto) as (broker, watcher, server):
        health = httpx.get(f"{server.base}/api/health").json()["mqtt"]
        assert health["state"] == "connected" and health["broker"] == broker.url
        with WsClient(server.ws) as ws:
            camera_id = add_camera(server.base, f"file://{motion_video}", name="yard")
            base = f"vigil/cameras/{camera_id}"
            # Its states as soon as it is added: still, stopped, automatic sensitivity.
            watcher.wait(f"{base}/motion", "OFF")
            watcher.wait(f"{base}/active", "OFF")
            watcher.wait(f"{base}/sensitivity", "auto")
            mark = watcher.mark()
            httpx.post(f"{server.base}/api/cameras/{camera_id}/activate").raise_for_status()
            watcher.wait(f"{base}/active", "ON", after=mark)

            alarm = ws.wait("alarm", 30, camera_id=camera_id)[0]
            motion_on = watcher.wait(f"{base}/motion", "ON", after=mark)
            assert motion_on.retain is False  # A live delivery; the broker keeps it.
            after_on = watcher.index(motion_on) + 1
            event = watcher.wait(f"{base}/event", after=after_on)
            assert json.loads(event.payload) == _ws_fields(alarm)  # The same fields as /ws.
            snapshot = watcher.wait(f"{base}/snapshot", after=after_on)
            picture = cv2.imdecode(np.frombuffer(snapshot.payload, np.uint8), cv2.IMREAD_COLOR)
            assert snapshot.payload[:2] == b"\xff\xd8" and picture is not None
            assert picture.shape[:2] == (240, 320)
            served = httpx.get(f"{server.base}{alarm['snapshot']}").content
            assert snapshot.payload == served
            # MQTT's motion ON as soon as the alarm is on the bus: beside /ws's alarm.
            lag = motion_on.at - alarm["_received"]
            print(f"motion ON on the broker {lag * 1000:+.1f} ms after the alarm on /ws")
            assert lag < 0.5

            end = ws.wait("motion_end", 30, camera_id=camera_id, event_id=alarm["event_id"])[0]
            motion_off = watcher.wait(f"{base}/motion", "OFF", after=after_on)
            ended = watcher.wait(f"{base}/event", after=watcher.index(motion_off) + 1)
            assert json.loads(ended.payload) == _ws_fields(end)

            httpx.post(f"{server.base}/api/cameras/{camera_id}/stop").raise_for_status()
            watcher.wait(f"{base}/active", "OFF", after=after_on)
            wait_for(
                lambda: (last := watcher.last(f"{base}/motion")) and last.text == "OFF",
                10,
                "motion OFF after Stop",
            )
            last_alarm = ws.of_type("alarm", camera_id=camera_id)[-1]

        # What a client that connects now is told: the truth, retained.
        held = retained(broker.port, ("vigil/#",))
        assert held["vigil/status"] == b"online"
        assert held[f"{base}/motion"] == b"OFF"
        assert held[f"{base}/active"] == b"OFF"
        assert held[f"{base}/sensitivity"] == b"auto"
        latest = httpx.get(f"{server.base}{last_alarm['snapshot']}").content
        assert held[f"{base}/snapshot"] == latest
        assert f"{base}/event" not in held  # Events are not retained.


def test_online_then_offline_on_a_clean_stop_with_the_event_ended(
    serve: Serve, mosquitto: Broker, motion_video: Path
) -> None:
    with _watched(serve, mosquitto) as (broker, watcher, server):
        camera_id = add_camera(server.base, f"file://{motion_video}", activate=True)
        watcher.wait(f"vigil/cameras/{camera_id}/motion", "ON", timeout=30)
        mark = watcher.mark()
        server.stop()
        offline = watcher.wait("vigil/status", "offline", after=mark)
        motion = watcher.on(f"vigil/cameras/{camera_id}/motion")[-1]
        assert motion.text == "OFF" and motion.at <= offline.at
    held = retained(broker.port, ("vigil/#",))
    assert held["vigil/status"] == b"offline"
    assert held[f"vigil/cameras/{camera_id}/motion"] == b"OFF"


def test_the_will_says_offline_when_the_server_is_killed(tmp_path: Path, mosquitto: Broker) -> None:
    broker = mosquitto()
    env = {"VIGIL_MQTT_URL": broker.url, "VIGIL_DEMO_CAMERA": "false"}
    with (
        Watcher(broker.port, ("vigil/status",)) as watcher,
        serve_process(tmp_path / "data", **env) as (process, _),
    ):
        watcher.wait("vigil/status", "online")
        mark = watcher.mark()
        os.kill(process.pid, signal.SIGKILL)
        process.wait(10)
        # Nobody at Vigil's end said it: the broker did, from the will.
        watcher.wait("vigil/status", "offline", after=mark, timeout=10)
    assert retained(broker.port, ("vigil/status",)) == {"vigil/status": b"offline"}
    assert "vigil-" in broker.log.read_text()  # Its client id names it in the broker's log.


def test_commands_act_as_the_api_does_and_bad_ones_are_ignored(
    serve: Serve, mosquitto: Broker, motion_video: Path, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="vigil.mqtt")
    with _watched(serve, mosquitto) as (_, watcher, server):
        camera_id = add_camera(server.base, f"file://{motion_video}")
        base = f"vigil/cameras/{camera_id}"
        watcher.wait(f"{base}/active", "OFF")
        with WsClient(server.ws) as ws:
            watcher.publish(f"{base}/active/set", "ON")
            wait_for(lambda: _camera(server, camera_id)["active"], 10, "Activate by MQTT")
            watcher.wait(f"{base}/active", "ON")
            ws.wait("status", 10, camera_id=camera_id, active=True)  # The page sees it.
            mark = watcher.mark()
            watcher.publish(f"{base}/active/set", "off")
            wait_for(lambda: not _camera(server, camera_id)["active"], 10, "Stop by MQTT")
            watcher.wait(f"{base}/active", "OFF", after=mark)
            ws.wait("status", 10, camera_id=camera_id, active=False)

            watcher.publish(f"{base}/sensitivity/set", "40")
            wait_for(lambda: _camera(server, camera_id)["sensitivity"] == 40, 10, "40")
            watcher.wait(f"{base}/sensitivity", "40")
            ws.wait("status", 10, camera_id=camera_id, sensitivity=40)
            for bad in ("0", "256", "abc", "nan", ""):
                watcher.publish(f"{base}/sensitivity/set", bad)
            watcher.publish(f"{base}/active/set", "maybe")
            watcher.publish("vigil/cameras/999/active/set", "ON")
            watcher.publish(f"{base}/sensitivity/set", "12.5")  # After the bad ones: in order.
            wait_for(lambda: _camera(server, camera_id)["sensitivity"] == 12.5, 10, "12.5")
            watcher.wait(f"{base}/sensitivity", "12.5")
            mark = watcher.mark()
            watcher.publish(f"{base}/sensitivity/set", "auto")
            wait_for(lambda: _camera(server, camera_id)["sensitivity"] is None, 10, "auto")
            watcher.wait(f"{base}/sensitivity", "auto", after=mark)
    ignored = [r.getMessage() for r in caplog.records if "ignored" in r.getMessage()]
    assert len(ignored) == 7, ignored
    assert any("not ON or OFF" in line for line in ignored)
    assert any("no camera 999" in line for line in ignored)
    assert any("from 1 to 255" in line for line in ignored)
    assert httpx.get(f"{server.base}/api/cameras").json()[0]["sensitivity"] is None


def _configs(watcher: Watcher, camera_id: int, after: int = 0) -> dict[str, dict[str, Any]]:
    """The latest config of each of the camera's five entities, by component."""
    found: dict[str, dict[str, Any]] = {}
    for component in COMPONENTS:
        what = {"binary_sensor": "motion", "switch": "active", "number": "sensitivity"}.get(
            component, "sensitivity_auto" if component == "button" else "snapshot"
        )
        topic = f"homeassistant/{component}/vigil_{camera_id}_{what}/config"
        message = watcher.wait(topic, after=after)
        found[component] = json.loads(watcher.on(topic)[-1].payload or b"null") or {}
        assert message.topic == topic
    return found


def test_discovery_adds_renames_and_removes_a_cameras_entities(
    serve: Serve, mosquitto: Broker, motion_video: Path
) -> None:
    with _watched(serve, mosquitto) as (broker, watcher, server):
        camera_id = add_camera(server.base, f"file://{motion_video}", name="porch")
        configs = _configs(watcher, camera_id)
        for component, config in configs.items():
            assert problems(component, config) == [], (component, config)
            assert config["availability_topic"] == "vigil/status"
            assert config["device"]["name"] == "porch"
            assert config["device"]["manufacturer"] == "Vigil"
            assert config["device"]["sw_version"] == __version__
        assert configs["binary_sensor"]["device_class"] == "motion"
        assert configs["binary_sensor"]["state_topic"] == f"vigil/cameras/{camera_id}/motion"
        assert configs["image"]["image_topic"] == f"vigil/cameras/{camera_id}/snapshot"
        assert configs["image"]["content_type"] == "image/jpeg"
        identifiers = {json.dumps(c["device"]["identifiers"]) for c in configs.values()}
        assert len(identifiers) == 1  # One device for the five.

        mark = watcher.mark()
        httpx.patch(f"{server.base}/api/cameras/{camera_id}", json={"name": "back porch"})
        renamed = _configs(watcher, camera_id, after=mark)
        assert {c["device"]["name"] for c in renamed.values()} == {"back porch"}
        assert {c["unique_id"] for c in renamed.values()} == {
            c["unique_id"] for c in configs.values()
        }

        held = retained(broker.port, ("homeassistant/#", "vigil/#"))
        assert sum(topic.startswith("homeassistant/") for topic in held) == 5
        mark = watcher.mark()
        httpx.delete(f"{server.base}/api/cameras/{camera_id}").raise_for_status()
        for component in COMPONENTS:
            topic = next(t for t in held if t.startswith(f"homeassistant/{component}/"))
            assert watcher.wait(topic, b"", after=mark).payload == b""
        watcher.wait(f"vigil/cameras/{camera_id}/snapshot", b"", after=mark)  # The last.
    held = retained(broker.port, ("homeassistant/#", "vigil/#"))
    assert held == {"vigil/status": b"online"}, held


def test_another_prefix_and_discovery_off(
    serve: Serve, mosquitto: Broker, motion_video: Path
) -> None:
    settings = {"mqtt_discovery_prefix": ""}
    with _watched(serve, mosquitto, "home/cams", **settings) as (_, watcher, server):
        camera_id = add_camera(server.base, f"file://{motion_video}", activate=True)
        watcher.wait(f"home/cams/cameras/{camera_id}/active", "ON")
        watcher.publish(f"home/cams/cameras/{camera_id}/active/set", "OFF")
        wait_for(lambda: not _camera(server, camera_id)["active"], 10, "Stop by MQTT")
    assert not [m for m in watcher.messages if not m.topic.startswith("home/cams/")]


def test_a_broker_with_passwords(serve: Serve, mosquitto: Broker, motion_video: Path) -> None:
    broker = mosquitto(users={"vigil": "s3cr:et@"})
    url = f"mqtt://vigil:s3cr%3Aet%40@127.0.0.1:{broker.port}"
    server = serve(mqtt_url=url, mqtt_reconnect_max_s=1.0)
    wait_for(
        lambda: httpx.get(f"{server.base}/api/health").json()["mqtt"]["state"] == "connected",
        10,
        "MQTT connected with its password",
    )
    refused = serve(
        Path(str(broker.folder)) / "other-data",
        mqtt_url=f"mqtt://vigil:wrong-password@127.0.0.1:{broker.port}",
    )
    health = wait_for(
        lambda: (
            (h := httpx.get(f"{refused.base}/api/health").json()["mqtt"])["state"] == "disconnected"
            and "reason" in h
            and "not connected yet" not in h["reason"]
            and h
        ),
        10,
        "the refusal",
    )
    assert "authori" in health["reason"].lower() or "password" in health["reason"].lower()
    assert health["broker"] == f"mqtt://vigil@127.0.0.1:{broker.port}"
    assert "wrong-password" not in json.dumps(health)
