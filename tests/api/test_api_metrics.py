"""``GET /metrics``: Prometheus' text format with the figures the camera processes report."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import httpx
from prometheus_client.parser import text_string_to_metric_families

from tests.api.vigil_livekit import Running, WsClient, add_camera, wait_for
from tests.mqtt.mosquitto import Mosquitto
from tests.notify.receivers import WebhookReceiver

PASSWORD = "metrics-secret-42"
Samples = dict[tuple[str, tuple[tuple[str, str], ...]], float]


def scrape(server: Running, **request: object) -> Samples:
    """Every sample of ``/metrics``, by name and labels."""
    response = httpx.get(f"{server.base}/metrics", **request)  # type: ignore[arg-type]
    response.raise_for_status()
    assert response.headers["content-type"].startswith("text/plain")
    return {
        (sample.name, tuple(sorted(sample.labels.items()))): sample.value
        for family in text_string_to_metric_families(response.text)
        for sample in family.samples
    }


def camera_sample(samples: Samples, metric: str, camera: int, **labels: str) -> float:
    return samples[(metric, tuple(sorted({"camera": str(camera), **labels}.items())))]


def poll(server: Running, condition: Callable[[Samples], bool], what: str) -> Samples:
    """The first scrape, within 5 s, whose samples meet ``condition``."""
    found: list[Samples] = []

    def met() -> bool:
        found.append(scrape(server))
        return condition(found[-1])

    wait_for(met, 5, what)
    return found[-1]


def test_metrics_report_a_camera_that_detects_and_raises_an_alarm(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    server = serve()
    cam = add_camera(server.base, f"file://{motion_video}", name="gate")
    before = poll(server, lambda s: camera_sample(s, "vigil_camera_up", cam) == 1, "camera up")
    assert camera_sample(before, "vigil_camera_info", cam, name="gate") == 1
    assert camera_sample(before, "vigil_camera_active", cam) == 0
    assert camera_sample(before, "vigil_camera_detect_seconds_count", cam) == 0
    with WsClient(server.ws) as ws:
        httpx.post(f"{server.base}/api/cameras/{cam}/activate").raise_for_status()
        ws.wait("alarm", 15, camera_id=cam)
        # The event lasts 2 s more: a status within it carries the alarm's count.
        during = poll(
            server, lambda s: camera_sample(s, "vigil_alarms_total", cam) >= 1, "the alarm counted"
        )
        ws.wait("motion_end", 15, camera_id=cam)
    assert during[("vigil_events_open", ())] == 1
    assert during[("vigil_snapshots_bytes", ())] > 0
    assert camera_sample(during, "vigil_camera_active", cam) == 1
    frames_read = camera_sample(during, "vigil_camera_frames_total", cam)
    assert frames_read > camera_sample(before, "vigil_camera_frames_total", cam)
    after = poll(server, lambda s: s[("vigil_events_open", ())] == 0, "the event ended")
    # Its clip is written within 2 s of the event's end.
    poll(server, lambda s: s[("vigil_clips_bytes", ())] > 0, "the clip counted")
    detected = camera_sample(after, "vigil_camera_detect_seconds_count", cam)
    assert detected > camera_sample(during, "vigil_camera_detect_seconds_count", cam) > 0
    # Cumulative buckets end at every frame detected: a 320-wide frame takes under 1 s.
    assert camera_sample(after, "vigil_camera_detect_seconds_bucket", cam, le="1.0") == detected
    assert camera_sample(after, "vigil_camera_detect_seconds_bucket", cam, le="+Inf") == detected
    assert 0 < camera_sample(after, "vigil_camera_detect_seconds_sum", cam) < detected


def test_metrics_need_the_password_and_take_basic_auth(serve: Callable[..., Running]) -> None:
    server = serve(password=PASSWORD, demo_camera=True)
    assert httpx.get(f"{server.base}/metrics").status_code == 401
    samples = scrape(server, auth=("prometheus", PASSWORD))
    assert any(name == "vigil_camera_up" for name, _ in samples)


def test_metrics_count_notifications_by_target(
    serve: Callable[..., Running], motion_video: Path
) -> None:
    webhook = WebhookReceiver().start()
    try:
        server = serve()
        answer = httpx.post(f"{server.base}/api/notifications", json={"url": webhook.url()})
        target = (("service", "JSON"), ("target", str(answer.json()["id"])))
        add_camera(server.base, f"file://{motion_video}", activate=True)
        webhook.wait(1, timeout=30)
        samples = poll(
            server,
            lambda s: s.get(("vigil_notifications_sent_total", target)) == 1,
            "the message counted",
        )
    finally:
        webhook.stop()
    assert samples[("vigil_notifications_failed_total", target)] == 0


def test_metrics_say_whether_mqtt_is_connected(
    serve: Callable[..., Running], mosquitto: Callable[..., Mosquitto], tmp_path: Path
) -> None:
    without = serve()
    assert not any(name == "vigil_mqtt_connected" for name, _ in scrape(without))
    broker = mosquitto()
    server = serve(tmp_path / "with", mqtt_url=broker.url, mqtt_reconnect_max_s=0.5)
    poll(server, lambda s: s.get(("vigil_mqtt_connected", ())) == 1, "MQTT connected")
    broker.stop()
    poll(server, lambda s: s.get(("vigil_mqtt_connected", ())) == 0, "MQTT down")
