"""``/api/notifications`` on a real server: list, add, delete, test; secrets masked in every
answer and log line; URLs Apprise refuses, refused with nothing stored."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path

import httpx
import pytest

from tests.api.test_api_browser_dashboard import publish
from tests.api.vigil_livekit import Running, add_camera, free_port, wait_for
from tests.notify.receivers import WebhookReceiver
from tests.notify.test_notify_delivery import snapshot_alarm, target_state

SECRET = "s3cretPassw0rd"
TOKEN = "AAHfakeBotTokenNotReal123"


def api(server: Running) -> str:
    return f"{server.base}/api/notifications"


def stored(server: Running) -> list[dict[str, object]]:
    """The targets in the database itself, not as the API shows them."""
    return list(server.server.config.app.state.services.database.targets())


def test_targets_are_added_listed_kept_and_deleted_with_their_secrets_masked(
    serve: Callable[..., Running], webhook: WebhookReceiver, tmp_path: Path
) -> None:
    data = tmp_path / "data"
    server = serve(data)
    assert httpx.get(api(server)).json() == []
    cam = add_camera(server.base, "demo", name="door")
    secret_hook = f"json://vigil:{SECRET}@127.0.0.1:{webhook.port}/hook?+X-Token=hdr{SECRET}"
    urls = {
        "webhook": (secret_hook, f"json://vigil:***@127.0.0.1:{webhook.port}/hook?+X-Token=***"),
        "telegram": (f"tgram://123456789:{TOKEN}/4242", "tgram://***:***/4242"),
        "ntfy": (
            "ntfys://vigil:pw1234@ntfy.example.net/door",
            "ntfys://vigil:***@ntfy.example.net/door",
        ),
        "discord": (f"discord://98765/{TOKEN}", "discord://***/***"),
    }
    answers = {}
    for name, (url, _) in urls.items():
        answer = httpx.post(
            api(server), json={"url": url, "cameras": [cam] if name == "ntfy" else None}
        )
        assert answer.status_code == 201, answer.text
        answers[name] = answer
    listed = httpx.get(api(server))
    for text in [listed.text, *(a.text for a in answers.values())]:
        assert SECRET not in text and TOKEN not in text and "pw1234" not in text
    shown = {t["service"]: t for t in listed.json()}
    assert sorted(shown) == ["Discord", "JSON", "Telegram", "ntfy"]
    assert [t["url"] for t in listed.json()] == [masked for _, masked in urls.values()]
    webhook_target = shown["JSON"]
    assert webhook_target == answers["webhook"].json()
    assert webhook_target | {"id": 0, "created_at": 0} == {
        "id": 0,
        "url": urls["webhook"][1],
        "service": "JSON",
        "cameras": None,
        "origin": "api",
        "created_at": 0,
        "sent": 0,
        "failed": 0,
        "pending": 0,
        "last_sent_at": None,
        "last_error": None,
        "last_error_at": None,
        "failing": False,
    }
    assert shown["ntfy"]["cameras"] == [cam]
    # The database keeps the URL whole: it is what is sent to.
    assert [t["url"] for t in stored(server)] == [url for url, _ in urls.values()]

    # The same URL twice: refused, named.
    again = httpx.post(api(server), json={"url": secret_hook})
    assert again.status_code == 409
    assert f"target {webhook_target['id']}" in again.json()["detail"] and SECRET not in again.text

    # Kept across a restart, ids and cameras alike.
    server.stop()
    server = serve(data)
    assert [(t["id"], t["url"], t["cameras"]) for t in httpx.get(api(server)).json()] == [
        (t["id"], t["url"], t["cameras"]) for t in listed.json()
    ]
    telegram = shown["Telegram"]["id"]
    assert httpx.delete(f"{api(server)}/{telegram}").status_code == 204
    assert httpx.delete(f"{api(server)}/{telegram}").status_code == 404
    assert httpx.post(f"{api(server)}/{telegram}/test").status_code == 404
    assert telegram not in [t["id"] for t in httpx.get(api(server)).json()]
    assert telegram not in [t["id"] for t in stored(server)]


@pytest.mark.parametrize(
    ("body", "said"),
    [
        ({"url": f"tgram://{TOKEN}/12"}, "Apprise cannot use this Telegram URL"),
        ({"url": f"tgramm://123:{TOKEN}/12"}, "Apprise knows no service tgramm://"),
        ({"url": f"https://hooks.example.net/{TOKEN}"}, "Apprise knows no service https://"),
        ({"url": f"discord://1234{TOKEN}"}, "Discord Webhook Token"),
        ({"url": TOKEN}, "not a URL"),
        ({"url": "   "}, "give an Apprise URL"),
        ({"url": f"json://host/\n{TOKEN}"}, "control characters"),
        ({"url": "json://vigil:***@host/hook"}, "*** is how Vigil shows a secret"),
        ({"url": "json://host/" + "x" * 5000}, "at most 4000 characters"),
        ({"url": "json://host/", "cameras": []}, "at least one camera"),
        ({"url": "json://host/", "cameras": [77]}, "no camera 77"),
        ({"url": "json://host/", "cameras": ["1"]}, "valid integer"),
        ({"url": 12}, "valid string"),
        ({"cameras": None}, "Field required"),
        ({"url": "json://host/", "cameras": None, "urls": []}, "Extra inputs"),
    ],
)
def test_a_url_apprise_refuses_is_a_clear_422_with_nothing_stored(
    serve: Callable[..., Running], body: dict[str, object], said: str
) -> None:
    server = serve()
    answer = httpx.post(api(server), json=body)
    assert answer.status_code == 422, answer.text
    assert said in answer.text
    assert TOKEN not in answer.text
    assert httpx.get(api(server)).json() == [] and stored(server) == []


def test_a_test_message_says_whether_it_went(
    serve: Callable[..., Running], webhook: WebhookReceiver, hanging_webhook: WebhookReceiver
) -> None:
    server = serve(notify_timeout_s=1.5, public_url="http://vigil.local:8000/")
    good = httpx.post(api(server), json={"url": webhook.url()}).json()
    answer = httpx.post(f"{api(server)}/{good['id']}/test")
    assert answer.status_code == 200
    assert answer.json()["ok"] is True and answer.json()["error"] is None
    (call,) = webhook.wait(1)
    assert call.body["title"] == "Vigil: test message"
    assert "this target works" in call.body["message"]
    assert "Dashboard: http://vigil.local:8000/" in call.body["message"]

    # Nothing listening: no, and why.
    refused = httpx.post(api(server), json={"url": f"json://127.0.0.1:{free_port()}/x"}).json()
    result = httpx.post(f"{api(server)}/{refused['id']}/test").json()
    assert result["ok"] is False and "connection refused" in result["error"]

    # A target that never answers: no, within the timeout, past the queue.
    hanging = httpx.post(api(server), json={"url": hanging_webhook.url()}).json()
    started = time.monotonic()
    result = httpx.post(f"{api(server)}/{hanging['id']}/test", timeout=10).json()
    assert time.monotonic() - started < 4.0
    assert result == {
        "ok": False,
        "error": "no answer within 1.5 s",
        "elapsed_s": result["elapsed_s"],
    }
    # Tests are not counted with the alarms' messages.
    assert target_state(server, good["id"])["sent"] == 0


def test_no_log_line_and_no_error_shown_holds_a_target_s_secret(
    serve: Callable[..., Running], caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.DEBUG, logger="vigil")
    server = serve(notify_retries=1, notify_retry_s=0.1)
    port = free_port()  # Nothing listens: every send fails.
    url = f"json://vigil:{SECRET}@127.0.0.1:{port}/{TOKEN}?token={TOKEN}x"
    target = httpx.post(api(server), json={"url": url}).json()
    publish(server, snapshot_alarm(server, 1, 1, time.time()))
    state = wait_for(
        lambda: (s := target_state(server, target["id"]))["failed"] == 1 and s, 10, "a failure"
    )
    tested = httpx.post(f"{api(server)}/{target['id']}/test").text
    assert "connection refused" in state["last_error"]
    logged = "\n".join(r.getMessage() for r in caplog.records)
    assert "failing" in logged and f"127.0.0.1:{port}" in logged
    for text in (logged, str(state), tested):
        assert SECRET not in text and f"token={TOKEN}" not in text


def test_targets_need_the_password_when_one_is_set(
    serve: Callable[..., Running], webhook: WebhookReceiver
) -> None:
    server = serve(password="correct horse")
    for method, path in [("GET", ""), ("POST", ""), ("DELETE", "/1"), ("POST", "/1/test")]:
        answer = httpx.request(method, api(server) + path, json={"url": webhook.url()})
        assert answer.status_code == 401, (method, path)
    assert stored(server) == [] and webhook.attempts == 0
    login = httpx.post(api(server), json={"url": webhook.url()}, auth=("vigil", "correct horse"))
    assert login.status_code == 201
