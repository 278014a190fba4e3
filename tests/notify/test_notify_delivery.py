"""Notifications sent by a real server to real receivers on loopback: a JSON webhook and an
SMTP server, from a real camera's alarm (a video file with a square crossing) or from
alarms put on the server's bus as a camera process forwards them."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import pytest

from app.api.app import create_app
from app.core.config import Settings
from tests.api.test_api_browser_dashboard import alarm as alarm_message
from tests.api.test_api_browser_dashboard import publish
from tests.api.vigil_livekit import Running, WsClient, add_camera, add_snapshot, wait_for
from tests.notify.receivers import MailReceiver, WebhookReceiver

PUBLIC = "https://vigil.example.net"


def add_target(server: Running, url: str, cameras: list[int] | None = None) -> dict[str, Any]:
    answer = httpx.post(f"{server.base}/api/notifications", json={"url": url, "cameras": cameras})
    assert answer.status_code == 201, answer.text
    return dict(answer.json())


def target_state(server: Running, target_id: int) -> dict[str, Any]:
    listed = httpx.get(f"{server.base}/api/notifications").json()
    return next(t for t in listed if t["id"] == target_id)


def snapshot_alarm(
    server: Running, camera_id: int, event_id: int, ts: float, name: str = "yard"
) -> dict[str, Any]:
    """An alarm as a camera sends it, with a real snapshot (file and row) of its own."""
    snapshot_id = add_snapshot(server, camera_id, ts, event_id=event_id)
    message = alarm_message(camera_id, event_id, ts, name)
    message["objects"][0]["distance_px"] = 2.0
    message["snapshot_id"] = snapshot_id
    message["snapshot"] = f"/api/snapshots/{snapshot_id}.jpg"
    return message


def event_of(hook_message: str) -> int:
    line = next(line for line in hook_message.splitlines() if line.startswith("Event "))
    return int(line.split()[1].rstrip(","))


def test_an_event_s_start_reaches_a_webhook_with_its_snapshot_and_a_link(
    serve: Callable[..., Running], webhook: WebhookReceiver, motion_video: Path
) -> None:
    server = serve(public_url=PUBLIC)
    target = add_target(server, webhook.url())
    with WsClient(server.ws) as ws:
        cam = add_camera(server.base, f"file://{motion_video}", name="Front door", activate=True)
        first = ws.wait("alarm", 30, camera_id=cam)[0]
        hook = webhook.wait(1)[0]
    assert hook.at - first["_received"] < 2.0, "the webhook came late"
    assert hook.path == "/hook"
    assert hook.body["title"] == "Motion on Front door"
    text = hook.body["message"]
    assert event_of(text) == first["event_id"]
    assert text.startswith("Motion on Front door at " + time.strftime("%Y-%m-%d"))
    objects = first["objects"]
    assert f"{len(objects)} object{'s' if len(objects) > 1 else ''} moving:" in text
    for item in objects:  # What moved: each object's box, area and speed.
        _, _, w, h = item["box"]
        said = f"#{item['track_id']}: {w}×{h} px box, {item['area']:,.0f} px moving,"
        assert f"- {said} {item['speed_px_s']:.0f} px/s" in text
    assert f"Snapshot: {PUBLIC}/api/snapshots/{first['snapshot_id']}.jpg" in text
    assert f"Dashboard: {PUBLIC}/" in text
    ((name, mime, data),) = hook.attachments
    assert mime == "image/jpeg" and name == f"vigil-Front-door-event{first['event_id']}.jpg"
    assert data == httpx.get(server.base + first["snapshot"]).content  # The snapshot itself.
    state = wait_for(
        lambda: (s := target_state(server, target["id"]))["sent"] >= 1 and s, 5, "the count"
    )
    assert state["failed"] == 0 and state["last_error"] is None and not state["failing"]
    assert state["last_sent_at"] is not None


def test_an_e_mail_arrives_over_smtp_with_the_snapshot_attached(
    serve: Callable[..., Running], mailbox: MailReceiver
) -> None:
    server = serve()
    add_target(server, mailbox.url(to="me@example.com"))
    message = snapshot_alarm(server, 3, 12, time.time(), name="Garage")
    publish(server, message)
    (mail,) = mailbox.wait(1)
    assert mail["Subject"] == "Motion on Garage"
    assert mail["To"] == "me@example.com" and mail["From"] == "vigil@example.com"
    body = mail.get_body(preferencelist=("plain",))
    assert body is not None and "Event 12, camera 3." in body.get_content()
    assert "Snapshot:" not in body.get_content()  # No VIGIL_PUBLIC_URL: no links.
    (picture,) = list(mail.iter_attachments())
    assert picture.get_content_type() == "image/jpeg"
    assert picture.get_filename() == "vigil-Garage-event12.jpg"
    stored = httpx.get(f"{server.base}{message['snapshot']}").content
    assert picture.get_content() == stored


def test_a_target_that_never_answers_delays_neither_another_target_nor_the_websocket(
    serve: Callable[..., Running],
    webhook: WebhookReceiver,
    hanging_webhook: WebhookReceiver,
    motion_video: Path,
) -> None:
    server = serve(notify_timeout_s=30.0)  # The hanging one holds each attempt 30 s.
    hanging = add_target(server, hanging_webhook.url())
    add_target(server, webhook.url())
    with WsClient(server.ws) as ws:
        cam = add_camera(server.base, f"file://{motion_video}", name="lane", activate=True)
        alarms = ws.wait("alarm", 30, count=2, camera_id=cam)
        events = sorted({a["event_id"] for a in ws.of_type("alarm", camera_id=cam)})
        hooks = webhook.wait(1)
        # /ws had each alarm within a moment of the camera's own time, while the hanging
        # target held its first message.
        for message in alarms:
            assert message["_received"] - message["ts"] < 1.0, message
        assert hanging_webhook.attempts >= 1
        # The other target had the first event at once.
        first = next(a for a in alarms if a["event_id"] == events[0])
        assert hooks[0].at - first["_received"] < 2.0
        assert event_of(hooks[0].body["message"]) == events[0]
        # And every later event too, one after another, while the hanging one waits.
        later = ws.wait("alarm", 30, count=len(alarms) + 2, camera_id=cam)
        last_event = max(a["event_id"] for a in later)
        wait_for(
            lambda: last_event in {event_of(h.body["message"]) for h in webhook.received()},
            10,
            "the latest event's message",
        )
    state = target_state(server, hanging["id"])
    assert state["sent"] == 0 and state["pending"] >= 1


def test_at_most_one_message_per_event_and_target_within_the_gap(
    serve: Callable[..., Running], webhook: WebhookReceiver
) -> None:
    server = serve(notify_gap_s=30.0)
    add_target(server, webhook.url())
    t0 = time.time()
    publish(server, snapshot_alarm(server, 1, 7, t0))  # Event 7 starts: sent.
    webhook.wait(1)
    publish(server, snapshot_alarm(server, 1, 7, t0 + 2))  # Within the gap: not sent.
    publish(server, snapshot_alarm(server, 1, 7, t0 + 29.9))  # Still within: not sent.
    publish(server, snapshot_alarm(server, 2, 8, t0 + 3))  # Another event starts: sent.
    webhook.wait(2)
    publish(server, snapshot_alarm(server, 1, 7, t0 + 31))  # The gap over: one more.
    publish(server, snapshot_alarm(server, 1, 7, t0 + 32))  # Within the new gap: not.
    calls = webhook.wait(3)
    time.sleep(1.0)  # Time for any message that should not come.
    calls = webhook.received()
    assert [event_of(c.body["message"]) for c in calls] == [7, 8, 7]
    later = calls[2].body["message"]
    assert later.startswith("Still moving on yard at ")
    assert f"(since {time.strftime('%H:%M:%S', time.localtime(t0))})" in later
    # An event's end forgets it: the same id again (a new database) starts afresh.
    publish(
        server,
        {
            "type": "motion_end",
            "camera_id": 1,
            "event_id": 7,
            "ts": t0 + 40,
            "duration_s": 40.0,
            "max_area": 1200.0,
        },
    )
    publish(server, snapshot_alarm(server, 1, 7, t0 + 41))
    assert event_of(webhook.wait(4)[3].body["message"]) == 7


def test_a_target_limited_to_some_cameras_hears_only_theirs(
    serve: Callable[..., Running], webhook: WebhookReceiver
) -> None:
    server = serve()
    yard = add_camera(server.base, "demo", name="yard")
    door = add_camera(server.base, "demo", name="door")
    target = add_target(server, webhook.url(), cameras=[door])
    assert target["cameras"] == [door]
    t0 = time.time()
    publish(server, snapshot_alarm(server, yard, 1, t0, name="yard"))
    publish(server, snapshot_alarm(server, door, 2, t0 + 1, name="door"))
    (call,) = webhook.wait(1)
    time.sleep(0.5)
    assert len(webhook.received()) == 1 and call.body["title"] == "Motion on door"


def test_failed_sends_are_retried_counted_and_logged_once_per_spell(
    serve: Callable[..., Running], caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="vigil.notify")
    receiver = WebhookReceiver(fail_next=2).start()  # Two 500s, then it takes messages.
    try:
        server = serve(notify_retry_s=0.2, notify_retries=3)
        target = add_target(server, receiver.url())
        t0 = time.time()
        publish(server, snapshot_alarm(server, 1, 1, t0))
        receiver.wait(1)
        assert receiver.attempts == 3  # Two refused, the third taken.
        state = wait_for(
            lambda: (s := target_state(server, target["id"]))["sent"] == 1 and s, 5, "sent"
        )
        assert state["failed"] == 0 and not state["failing"]
        assert "error=500" in state["last_error"]  # Kept, with when.
        assert state["last_error_at"] >= t0

        # Now it refuses everything: each message is tried 4 times, then given up.
        receiver.mode = "error"
        for i in range(2):
            publish(server, snapshot_alarm(server, 1, 10 + i, t0 + 1 + i))
        failed = wait_for(
            lambda: (s := target_state(server, target["id"]))["failed"] == 2 and s, 15, "failed"
        )
        assert failed["failing"] and failed["sent"] == 1
        assert receiver.attempts == 3 + 2 * 4
        # Back: the next message goes, and the spell's end is logged.
        receiver.mode = "ok"
        publish(server, snapshot_alarm(server, 1, 20, t0 + 5))
        wait_for(lambda: target_state(server, target["id"])["sent"] == 2, 10, "sent again")
    finally:
        receiver.stop()
    said = [r.getMessage() for r in caplog.records if r.name == "vigil.notify"]
    failing = [m for m in said if " failing: " in m]
    again = [m for m in said if "works again" in m]
    # Two spells (11 failed attempts): each logged once at its start and once at its end.
    assert len(failing) == 2 and len(again) == 2, said
    assert "2 message(s) lost" in again[1]


def test_notify_urls_add_fixed_targets_at_start_and_a_bad_one_stops_the_start(
    serve: Callable[..., Running], webhook: WebhookReceiver, tmp_path: Path
) -> None:
    url = webhook.url("env") + " " + "tgram://123456789:AAHsecretsecretsecret/555"
    data = tmp_path / "data"
    server = serve(data, notify_urls=url)
    listed = httpx.get(f"{server.base}/api/notifications").json()
    assert [(t["origin"], t["service"]) for t in listed] == [("env", "JSON"), ("env", "Telegram")]
    assert listed[1]["url"] == "tgram://***:***/555"
    refused = httpx.delete(f"{server.base}/api/notifications/{listed[0]['id']}")
    assert refused.status_code == 409 and "VIGIL_NOTIFY_URLS" in refused.json()["detail"]
    publish(server, snapshot_alarm(server, 1, 1, time.time()))
    assert webhook.wait(1)[0].path == "/env"
    server.stop()

    # Started again without the Telegram URL: that target is gone, the other kept its id.
    again = serve(data, notify_urls=webhook.url("env"))
    relisted = httpx.get(f"{again.base}/api/notifications").json()
    assert [t["id"] for t in relisted] == [listed[0]["id"]]
    again.stop()

    # A URL Apprise cannot use: the server does not start, and says which, with no secret.
    with pytest.raises(ValueError, match="VIGIL_NOTIFY_URLS, URL 2: Apprise cannot use") as bad:
        create_app(Settings(data_dir=data, notify_urls=f"{webhook.url()} tgram://AAHsecret/1"))
    assert "AAHsecret" not in str(bad.value)


def test_a_target_that_never_answers_keeps_only_its_newest_messages_waiting(
    serve: Callable[..., Running], hanging_webhook: WebhookReceiver
) -> None:
    server = serve(notify_timeout_s=30.0)
    target = add_target(server, hanging_webhook.url())
    t0 = time.time()
    publish(server, snapshot_alarm(server, 1, 1, t0))
    wait_for(lambda: hanging_webhook.attempts == 1, 10, "the first message in flight")
    for event in range(2, 26):  # 24 more events: 20 wait, the 4 oldest of them are dropped.
        publish(server, snapshot_alarm(server, 1, event, t0 + event))
    state = wait_for(
        lambda: (s := target_state(server, target["id"]))["failed"] == 4 and s, 10, "drops"
    )
    assert state["pending"] == 20 and state["sent"] == 0 and state["failing"]
    assert state["last_error"] == "a message dropped: 20 were waiting for the target"
