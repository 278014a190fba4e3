"""The page's MQTT badge in Chromium: hidden without a broker, then as the broker goes."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from tests.api.vigil_livekit import Running
from tests.mqtt.mosquitto import Mosquitto, mqtt_settings

pytestmark = pytest.mark.browser


def test_the_top_bar_says_whether_mqtt_is_connected(
    serve: Callable[..., Running],
    mosquitto: Callable[..., Mosquitto],
    page: Any,
    tmp_path: Path,
) -> None:
    plain = serve(tmp_path / "plain")
    page.goto(plain.base + "/")
    page.wait_for_selector("#ws-state.badge-live")
    page.wait_for_timeout(500)  # Its health answered meanwhile.
    assert page.locator("#mqtt-state").is_hidden()

    broker = mosquitto()
    server = serve(tmp_path / "mqtt", **mqtt_settings(broker))
    page.goto(server.base + "/")
    badge = page.locator("#mqtt-state")
    page.wait_for_selector("#mqtt-state.badge-live")
    assert badge.inner_text() == "MQTT"
    assert badge.get_attribute("title") == f"MQTT: connected to {broker.url}"

    broker.kill()
    page.wait_for_selector("#mqtt-state.badge-error", timeout=15000)
    assert badge.inner_text() == "MQTT down"
    title = badge.get_attribute("title") or ""
    assert title.startswith(f"MQTT: not connected to {broker.url}: ")
    assert page.locator("#ws-state.badge-live").is_visible()  # The page itself is fine.

    broker.start()
    page.wait_for_selector("#mqtt-state.badge-live", timeout=15000)
    assert page.evaluate("window.__csp") == []
