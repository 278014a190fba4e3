"""A broker that goes away costs MQTT only: killed in the middle of an event and started
again, down when Vigil starts, or hung. Real Mosquitto, real uvicorn."""

from __future__ import annotations

import signal
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import httpx

from tests.api.vigil_livekit import (
    FPS,
    HEIGHT,
    WIDTH,
    Running,
    WsClient,
    add_camera,
    background,
    free_port,
    wait_for,
)
from tests.mqtt.mosquitto import Mosquitto, Watcher, mqtt_settings, retained

Serve = Callable[..., Running]
Broker = Callable[..., Mosquitto]


def write_moving_video(path: Path, frames: int = 60) -> Path:
    """A square that never stops moving (it jumps back to the left at the loop): one
    event that lasts as long as the camera is activated."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), FPS, (WIDTH, HEIGHT))
    assert writer.isOpened()
    base = background()
    for i in range(frames):
        gray = base.copy()
        x = 10 + 4 * i
        gray[90:130, x : x + 40] = 230
        writer.write(cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR))
    writer.release()
    return path


def _mqtt_health(server: Running, within_s: float = 2.0) -> dict[str, object]:
    """/api/health's ``mqtt``, answered within ``within_s`` seconds: well under the 5 s a
    publish waits for a hung broker's acknowledgement, with room for a loaded machine
    (0.73 s seen at a load average of 12)."""
    started = time.monotonic()
    answer = httpx.get(f"{server.base}/api/health", timeout=5)
    took = time.monotonic() - started
    assert answer.status_code == 200 and took < within_s, f"/api/health took {took:.2f} s"
    return dict(answer.json()["mqtt"])


def _state_is(server: Running, state: str) -> Callable[[], bool]:
    return lambda: _mqtt_health(server)["state"] == state


def test_broker_killed_mid_event_and_started_again(
    serve: Serve, mosquitto: Broker, motion_video: Path, tmp_path: Path
) -> None:
    # The broker keeps its retained messages across a kill: stale ones to be corrected.
    broker = mosquitto(persistence=True)
    server = serve(**mqtt_settings(broker))
    moving = write_moving_video(tmp_path / "moving.avi")
    with WsClient(server.ws) as ws:
        with Watcher(broker.port) as watcher:
            yard = add_camera(server.base, f"file://{motion_video}", name="yard", activate=True)
            lane = add_camera(server.base, f"file://{moving}", name="lane")
            gone = add_camera(server.base, f"file://{motion_video}", name="gone")
            watcher.wait(f"vigil/cameras/{lane}/active", "OFF")
            watcher.wait(f"vigil/cameras/{gone}/active", "OFF")
            watcher.wait(f"vigil/cameras/{yard}/motion", "ON", timeout=30)
            # Mid-event (the broker holds yard's motion ON), the broker dies.
            time.sleep(1.5)  # Mosquitto saves what it holds each second.
            broker.kill()

        wait_for(_state_is(server, "disconnected"), 10, "MQTT disconnected")
        health = _mqtt_health(server)
        assert health["reason"] and health["broker"] == broker.url
        # Meanwhile: yard is stopped (its event ends), lane starts moving, gone is deleted.
        # The page hears all of it at once, as before.
        ended = len(ws.of_type("motion_end", camera_id=yard))
        httpx.post(f"{server.base}/api/cameras/{yard}/stop").raise_for_status()
        ws.wait("motion_end", 10, count=ended + 1, camera_id=yard)
        alarms_before = len(ws.of_type("alarm"))
        httpx.post(f"{server.base}/api/cameras/{lane}/activate").raise_for_status()
        (alarm,) = ws.wait("alarm", 30, camera_id=lane)[:1]
        assert len(ws.of_type("alarm")) > alarms_before
        httpx.delete(f"{server.base}/api/cameras/{gone}").raise_for_status()
        for _ in range(5):  # Nothing waits for the broker.
            assert _mqtt_health(server)["state"] == "disconnected"
        assert alarm["_received"] - alarm["ts"] < 1.0

        # The persisted state is stale: a broker started on it shows yard still moving.
        stale_port = free_port()
        stale = Mosquitto(broker.folder, persistence=True, port=stale_port)
        stale.start()
        try:
            stored = retained(stale_port, ("vigil/#",))
        finally:
            stale.stop()
        assert stored[f"vigil/cameras/{yard}/motion"] == b"ON"
        assert stored[f"vigil/cameras/{lane}/motion"] == b"OFF"
        assert stored[f"vigil/cameras/{gone}/active"] == b"OFF"

        broker.start()  # Again, at its port, with what it had stored.
        wait_for(_state_is(server, "connected"), 10, "MQTT reconnected")
        wait_for(
            lambda: retained(broker.port, (f"vigil/cameras/{gone}/#",), 0.2) == {},
            10,
            "the deleted camera's retained topics cleared",
        )
        held = retained(broker.port, ("vigil/#", "homeassistant/#"))
        assert held["vigil/status"] == b"online"
        assert held[f"vigil/cameras/{yard}/motion"] == b"OFF"  # The event ended meanwhile.
        assert held[f"vigil/cameras/{yard}/active"] == b"OFF"
        assert held[f"vigil/cameras/{lane}/motion"] == b"ON"  # Started moving meanwhile.
        assert held[f"vigil/cameras/{lane}/active"] == b"ON"
        assert not [topic for topic in held if f"vigil_{gone}_" in topic]
        assert f"homeassistant/binary_sensor/vigil_{lane}_motion/config" in held
        assert held[f"vigil/cameras/{lane}/snapshot"][:2] == b"\xff\xd8"


def test_broker_down_at_start(serve: Serve, mosquitto: Broker, motion_video: Path) -> None:
    port = free_port()
    started = time.monotonic()
    server = serve(mqtt_url=f"mqtt://127.0.0.1:{port}", mqtt_reconnect_max_s=1.0)
    assert time.monotonic() - started < 15
    health = wait_for(
        lambda: (
            (h := _mqtt_health(server))["state"] == "disconnected"
            and "not connected yet" not in str(h.get("reason"))
            and h
        ),
        10,
        "the first attempt's failure",
    )
    assert "refused" in str(health["reason"]).lower()
    with WsClient(server.ws) as ws:
        camera_id = add_camera(server.base, f"file://{motion_video}", name="yard", activate=True)
        ws.wait("alarm", 30, camera_id=camera_id)  # Cameras work without the broker.
    broker = mosquitto(port=port)
    wait_for(_state_is(server, "connected"), 10, "MQTT connected once the broker is up")
    snapshot = f"vigil/cameras/{camera_id}/snapshot"
    held = wait_for(
        lambda: (h := retained(broker.port, ("vigil/#", "homeassistant/#"))).get(snapshot) and h,
        10,
        "the latest snapshot on the broker",
    )
    assert held["vigil/status"] == b"online"
    assert held[f"vigil/cameras/{camera_id}/active"] == b"ON"
    assert held[f"vigil/cameras/{camera_id}/motion"] in (b"ON", b"OFF")
    assert held[snapshot][:2] == b"\xff\xd8"
    assert f"homeassistant/switch/vigil_{camera_id}_active/config" in held


def test_a_hung_broker_blocks_nothing(serve: Serve, mosquitto: Broker, motion_video: Path) -> None:
    """A broker that stops answering (SIGSTOP: its connections stay open) fails MQTT's
    acknowledgements; /ws, the cameras and /api/health go on, and MQTT comes back."""
    broker = mosquitto()
    server = serve(**mqtt_settings(broker))
    with WsClient(server.ws) as ws:
        camera_id = add_camera(server.base, f"file://{motion_video}", activate=True)
        ws.wait("alarm", 30, camera_id=camera_id)
        assert broker.process is not None
        broker.process.send_signal(signal.SIGSTOP)
        try:
            count = len(ws.of_type("alarm", camera_id=camera_id))
            ws.wait("alarm", 15, count=count + 2, camera_id=camera_id)  # Alarms go on.
            for _ in range(5):
                _mqtt_health(server)
            wait_for(_state_is(server, "disconnected"), 20, "the hung broker noticed")
        finally:
            broker.process.send_signal(signal.SIGCONT)
        wait_for(_state_is(server, "connected"), 20, "MQTT back")
