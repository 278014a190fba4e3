"""The page's Notifications section in a real Chromium: a target added for some cameras,
refused with the server's reason, tested, its counts and last error shown as alarms go
out, removed; secrets never on the page; within the page's Content-Security-Policy."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import httpx
import pytest

from tests.api.test_api_browser_dashboard import publish
from tests.api.test_api_browser_editing import nowhere
from tests.api.vigil_livekit import Running, add_camera, free_port, wait_for
from tests.notify.receivers import WebhookReceiver
from tests.notify.test_notify_delivery import snapshot_alarm

pytestmark = pytest.mark.browser

SECRET = "s3cretPassw0rd"


def test_targets_are_added_tested_followed_and_removed_on_the_page(
    serve: Callable[..., Running], page: Any, webhook: WebhookReceiver
) -> None:
    server = serve(notify_retries=0, notify_urls=webhook.url("fixed"))
    door = add_camera(server.base, nowhere(), name="door")
    add_camera(server.base, nowhere(), name="yard")
    dialogs: list[str] = []
    page.on("dialog", lambda dialog: (dialogs.append(dialog.message), dialog.accept()))
    page.goto(server.base + "/")
    page.wait_for_selector("#ws-state.badge-live", timeout=10000)
    section = page.locator("#notifications")
    targets = section.locator(".target")
    wait_for(lambda: targets.count() == 1, 10, "the fixed target")
    fixed = targets.nth(0)
    assert "set by VIGIL_NOTIFY_URLS" in fixed.inner_text()
    assert fixed.get_by_role("button", name="Remove").count() == 0
    assert "all cameras" in fixed.inner_text()

    # A URL Apprise refuses: its reason on the form, nothing added.
    url = section.get_by_label("Apprise URL")
    url.fill("tgram://AAHnotatoken/12")
    url.press("Enter")
    error = section.locator("#add-target .form-error")
    wait_for(lambda: error.inner_text(), 10, "the refusal")
    assert "Apprise cannot use this Telegram URL" in error.inner_text()
    assert targets.count() == 1 and url.input_value() == "tgram://AAHnotatoken/12"

    # A webhook with a password, for the door only: listed masked, the form emptied.
    url.fill(f"json://vigil:{SECRET}@127.0.0.1:{webhook.port}/door")
    section.locator(".target-cameras summary").click()
    section.locator(".target-cameras").get_by_label("door").check()
    assert section.locator(".target-cameras summary").inner_text() == "1 camera"
    section.get_by_role("button", name="Add target").click()
    wait_for(lambda: targets.count() == 2, 10, "the new target")
    mine = targets.nth(1)
    assert mine.locator(".url").inner_text() == f"json://vigil:***@127.0.0.1:{webhook.port}/door"
    assert "door" in mine.locator(".scope").inner_text()
    assert mine.locator(".state").inner_text() == "no message yet"
    assert url.input_value() == "" and error.inner_text() == ""
    assert section.locator(".target-cameras summary").inner_text() == "all cameras"
    assert SECRET not in page.content()

    # A test message: sent, and said so.
    mine.get_by_role("button", name="Send a test").click()
    result = mine.locator(".test-result")
    wait_for(lambda: "sent" in result.inner_text(), 10, "the test's result")
    assert "not sent" not in result.inner_text()
    assert webhook.wait(1)[0].body["title"] == "Vigil: test message"

    # An alarm of the door: both targets send, and the page shows it without a reload.
    publish(server, snapshot_alarm(server, door, 5, time.time(), name="door"))
    wait_for(lambda: "1 sent" in mine.locator(".counts").inner_text(), 15, "the count")
    assert mine.locator(".state").inner_text() == "working"

    # A target that refuses: failing, its last error and when, on the page.
    httpx.post(
        f"{server.base}/api/notifications", json={"url": f"json://127.0.0.1:{free_port()}/x"}
    ).raise_for_status()
    publish(server, snapshot_alarm(server, door, 6, time.time(), name="door"))
    wait_for(lambda: targets.count() == 3, 15, "the third target")
    broken = targets.nth(2)
    wait_for(lambda: broken.locator(".target-error").count(), 15, "the error shown")
    assert broken.locator(".state").inner_text() == "failing"
    assert "connection refused" in broken.locator(".target-error").inner_text()
    assert "1 failed" in broken.locator(".counts").inner_text()
    broken_url = broken.locator(".url").inner_text()

    # Removed, after a question.
    mine.get_by_role("button", name="Remove").click()
    wait_for(lambda: targets.count() == 2, 10, "the target removed")
    assert len(dialogs) == 1 and "Stop sending alarms to JSON" in dialogs[0]
    assert SECRET not in dialogs[0]
    assert [t["url"] for t in httpx.get(f"{server.base}/api/notifications").json()] == [
        webhook.url("fixed"),
        broken_url,
    ]
    assert page.evaluate("window.__csp") == []
