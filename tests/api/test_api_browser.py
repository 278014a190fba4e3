"""The dashboard in a real Chromium (Playwright): picture, Activate -> alarm, slider, upload."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.api.vigil_livekit import Running, wait_for, write_video

pytestmark = pytest.mark.browser


def test_dashboard_in_chromium(
    serve: Callable[..., Running], page: Any, motion_video: Path, tmp_path: Path
) -> None:
    server = serve(demo_camera=True)
    base = server.base
    lane = httpx.post(
        f"{base}/api/cameras", json={"name": "lane", "source": f"file://{motion_video}"}
    ).json()["id"]
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.goto(base + "/")

    # The demo camera's picture renders.
    page.wait_for_function(
        "() => [...document.querySelectorAll('.card img.live')]"
        ".filter(i => i.naturalWidth > 0).length >= 2",
        timeout=20000,
    )
    card = page.locator(f'.card[data-id="{lane}"]')
    assert card.locator(".state").inner_text() == "live"

    # Activate leads to an alarm on the page: a toast and an entry in the list.
    card.locator("button.toggle").click()
    page.wait_for_selector("#alarm-list li", timeout=20000)
    page.wait_for_selector(".toast", timeout=5000)
    assert "lane" in page.locator("#alarm-list li").first.inner_text()
    assert card.locator("button.toggle").inner_text() == "Stop"

    # The slider changes the camera (and "auto" goes back to automatic).
    card.locator("input.sensitivity").fill("40")
    wait_for(
        lambda: httpx.get(f"{base}/api/cameras/{lane}").json()["sensitivity"] == 40,
        10,
        "the slider's sensitivity on the server",
    )
    card.locator("input.auto").check()
    wait_for(
        lambda: httpx.get(f"{base}/api/cameras/{lane}").json()["sensitivity"] is None,
        10,
        "automatic sensitivity",
    )

    # An upload shows progress and its result.
    video = write_video(tmp_path / "upload.avi", frames=90)
    page.set_input_files("#upload input[type=file]", str(video))
    page.click("#upload button[type=submit]")
    page.wait_for_selector(".analysis .status.badge-done", timeout=60000)
    panel = page.locator(".analysis").first
    assert panel.locator(".analysis-bar").evaluate("b => b.value") == 1
    assert panel.locator("table.tracks tbody tr").count() >= 1
    assert panel.locator("a", has_text="tracks.csv").count() == 1

    # The gallery shows the alarm's snapshots.
    page.click("#gallery-filter button[type=submit]")
    page.wait_for_selector("#thumbs figure", timeout=10000)
    assert errors == []


def test_more_cameras_than_connections_all_show(
    serve: Callable[..., Running], page: Any, motion_video: Path
) -> None:
    server = serve()
    for i in range(7):
        httpx.post(
            f"{server.base}/api/cameras",
            json={"name": f"cam{i}", "source": f"file://{motion_video}"},
        ).raise_for_status()
    page.goto(server.base + "/")
    # Seven pictures at once: more than a browser's six connections could stream.
    page.wait_for_function(
        "() => [...document.querySelectorAll('.card img.live')]"
        ".filter(i => i.naturalWidth > 0).length === 7",
        timeout=30000,
    )
    sources = page.locator(".card img.live").evaluate_all("imgs => imgs.map(i => i.src)")
    assert all("/frame.jpg" in s for s in sources), "many cameras are polled, not streamed"
    first = page.locator(".card img.live").first.get_attribute("src")
    page.wait_for_function(
        f"() => document.querySelector('.card img.live').src !== '{first}'", timeout=10000
    )
