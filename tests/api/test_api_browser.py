"""The dashboard in a real Chromium (Playwright): picture, Activate -> alarm, slider, upload."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.api.test_api_browser_dashboard import pictures_move
from tests.api.vigil_livekit import (
    ROOT,
    Running,
    add_camera,
    wait_for,
    wait_for_picture,
    wait_for_pictures,
    write_video,
)
from tests.sources.damaged_video import cut_after

pytestmark = pytest.mark.browser

MODULES = ROOT / "static" / "js"
"""The page's own code: native ES modules, served as they are (no build step)."""


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
    wait_for_pictures(page, 2, timeout_ms=20000, at_least=True)
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
    # No metre or km/h columns without a calibration; "1 event", not "1 events".
    assert panel.locator("table.tracks thead th").count() == 6
    summary = panel.locator(".result p").first.inner_text()
    assert re.search(r"\b(1 event|\d+ events),", summary)
    assert not re.search(r"(?<!\d)1 events", summary)
    assert panel.locator("a", has_text="tracks.csv").count() == 1

    # The gallery shows the alarm's snapshots.
    page.click("#gallery-filter button[type=submit]")
    page.wait_for_selector("#thumbs figure", timeout=10000)
    assert errors == []


def test_more_cameras_than_connections_all_show_over_one_socket(
    serve: Callable[..., Running], page: Any, motion_video: Path
) -> None:
    server = serve()
    # Seven pictures at once: more than a browser's six connections could stream. They
    # all come over the page's one /ws/live socket: no stream and no polled frame.
    sockets: list[str] = []
    page.on("websocket", lambda socket: sockets.append(socket.url))
    asked: list[str] = []
    page.on("request", lambda r: asked.append(r.url) if "/api/cameras/" in r.url else None)
    for i in range(7):
        add_camera(server.base, f"file://{motion_video}", name=f"cam{i}")
    page.goto(server.base + "/#wall")
    wait_for_pictures(page, 7)
    assert all(pictures_move(page))
    assert sorted(sockets) == sorted([server.ws, server.ws + "/live"]), sockets
    assert not [url for url in asked if "stream.mjpg" in url or "frame.jpg" in url], asked


def test_ignore_zones_drawn_on_the_picture_are_saved_and_shown(
    serve: Callable[..., Running], page: Any, motion_video: Path
) -> None:
    server = serve()
    cam = httpx.post(
        f"{server.base}/api/cameras", json={"name": "yard", "source": f"file://{motion_video}"}
    ).json()["id"]
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.goto(server.base + "/")
    card = page.locator(f'.card[data-id="{cam}"]')
    wait_for_picture(page, cam)
    card.locator("button.zones").click()
    layer = card.locator("svg.zone-layer")
    box = layer.bounding_box()
    assert box is not None and box["width"] > 50
    # Most of the left half of the frame, clicked corner by corner.
    expected = ((0.05, 0.05), (0.5, 0.05), (0.5, 0.95), (0.05, 0.95))
    for fx, fy in expected:
        layer.click(position={"x": fx * box["width"], "y": fy * box["height"]})
    card.locator("button.zone-save").click()
    ((zone),) = wait_for(
        lambda: httpx.get(f"{server.base}/api/cameras/{cam}").json()["mask"],
        10,
        "the zone on the server",
    )
    assert len(zone) == 4
    for (x, y), (ex, ey) in zip(zone, expected, strict=True):
        assert abs(x - ex) < 0.02 and abs(y - ey) < 0.02, zone
    page.reload()
    page.wait_for_selector(f'.card[data-id="{cam}"] svg.zone-layer polygon', timeout=20000)
    assert card.locator("svg.zone-layer polygon").count() == 1
    assert errors == []
    assert page.evaluate("window.__csp") == [], "the editor keeps to the page's CSP"


def test_an_upload_s_warnings_show_in_its_panel(
    serve: Callable[..., Running], page: Any, tmp_path: Path
) -> None:
    # A file cut short ends "done", its report warns it ended early: the panel said
    # nothing of it (outside audit).
    server = serve()
    whole = write_video(tmp_path / "whole.avi", frames=60)
    cut = cut_after(whole, 20, tmp_path / "cut.avi")
    page.goto(server.base + "/")
    page.set_input_files("#upload input[type=file]", str(cut))
    page.click("#upload button[type=submit]")
    page.wait_for_selector(".analysis .status.badge-done", timeout=60000)
    warning = page.locator(".analysis .warnings li").first.inner_text()
    assert warning.startswith("the video ended early: ") and "of the 60 its header" in warning


def test_a_min_area_the_camera_cannot_take_is_said_and_undone_on_the_page(
    serve: Callable[..., Running], page: Any
) -> None:
    # Typed -5, the field quietly went back to the area in force (outside audit).
    server = serve(demo_camera=True)
    page.goto(server.base + "/")
    area = page.locator(".card .min-area").first
    wait_for(lambda: area.input_value() == "100", 20, "the card")
    area.fill("-5")
    area.press("Enter")
    page.wait_for_selector(".toast >> text=a number of pixels, 0 or more", timeout=5000)
    assert area.input_value() == "100"
    assert httpx.get(f"{server.base}/api/cameras").json()[0]["min_area"] == 100


def test_the_page_runs_as_es_modules_within_its_content_security_policy(
    serve: Callable[..., Running], page: Any
) -> None:
    server = serve(demo_camera=True)
    errors: list[str] = []
    page.on(
        "console", lambda message: errors.append(message.text) if message.type == "error" else None
    )
    page.on("pageerror", lambda error: errors.append(str(error)))
    modules: list[str] = []
    page.on(
        "response",
        lambda answer: (
            modules.append(answer.url.split("/static/js/")[1])
            if "/static/js/" in answer.url
            and answer.ok
            and "javascript" in answer.headers["content-type"]
            else None
        ),
    )
    page.goto(server.base + "/")
    wait_for_pictures(page, 1, timeout_ms=20000)  # The demo camera's card, with its picture.
    page.wait_for_selector(".card .motion canvas")  # Drawn by the classic script's uPlot.
    scripts = page.locator("script").evaluate_all(
        "scripts => scripts.map(s => [s.type, s.getAttribute('src')])"
    )
    assert scripts == [
        ["", "/static/vendor/uplot/uPlot.iife.min.js"],
        ["module", "/static/js/main.js"],
    ]
    # Each module of static/js loaded, as JavaScript: none is left out of the page.
    assert sorted(modules) == sorted(
        p.relative_to(MODULES).as_posix() for p in MODULES.rglob("*.js")
    )
    assert page.evaluate("window.__csp") == []
    assert errors == []


def test_each_module_of_the_page_reads_at_once() -> None:
    lines = {p.name: len(p.read_text().splitlines()) for p in MODULES.rglob("*.js")}
    assert lines and max(lines.values()) <= 400, lines
