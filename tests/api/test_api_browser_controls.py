"""The dashboard's controls and connections in a real Chromium (Playwright): the sensitivity
slider in auto mode, an action while the server is down, a tab left in the background."""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.api.test_api_browser_dashboard import alarm, publish
from tests.api.vigil_livekit import (
    Running,
    add_snapshot,
    set_hidden,
    show_cameras,
    wait_for,
    watch_analysis_live,
)

pytestmark = pytest.mark.browser

STREAMS_OPEN = "() => document.querySelectorAll('img[src*=\".mjpg\"]').length"
"""How many pictures on the page hold an MJPEG stream."""


def test_the_slider_in_auto_mode_shows_the_threshold_in_force_and_a_nudge_starts_there(
    serve: Callable[..., Running], page: Any
) -> None:
    # In auto mode the slider sat at 128 whatever the threshold: with "auto (10)" shown,
    # one ArrowLeft (asking for more sensitivity) stored 127, far less sensitive.
    server = serve(demo_camera=True)
    cam = httpx.get(f"{server.base}/api/cameras").json()[0]["id"]
    httpx.post(f"{server.base}/api/cameras/{cam}/activate").raise_for_status()
    page.goto(server.base + "/")
    card = page.locator(f'.card[data-id="{cam}"]')
    shown = card.locator(".sens-value")
    wait_for(
        lambda: shown.count() and re.fullmatch(r"auto \(\d+\)", shown.inner_text()),
        20,
        "the threshold in force",
    )
    slider = card.locator("input.sensitivity")
    slider.focus()  # The card no longer redraws the slider nor its value.
    threshold = int(re.fullmatch(r"auto \((\d+)\)", shown.inner_text()).group(1))
    assert int(slider.input_value()) == threshold
    slider.press("ArrowLeft")
    wait_for(
        lambda: httpx.get(f"{server.base}/api/cameras/{cam}").json()["sensitivity"] is not None,
        10,
        "the sensitivity set on the server",
    )
    stored = httpx.get(f"{server.base}/api/cameras/{cam}").json()["sensitivity"]
    assert stored == max(1, threshold - 1)
    assert not card.locator("input.auto").is_checked()


def test_an_action_while_the_server_is_unreachable_says_so_in_words(
    serve: Callable[..., Running], page: Any
) -> None:
    # A fetch that gets no answer rejects with the browser's "Failed to fetch", which the
    # toast showed as it was.
    server = serve(demo_camera=True)
    cam = httpx.get(f"{server.base}/api/cameras").json()[0]["id"]
    page.goto(server.base + "/")
    method = page.locator(f'.card[data-id="{cam}"] .method')
    wait_for(lambda: method.count() and method.input_value() == "adaptive", 20, "the card")
    page.route(
        f"**/api/cameras/{cam}",
        lambda route: (
            route.abort("connectionrefused")
            if route.request.method == "PATCH"
            else route.continue_()
        ),
    )
    method.select_option("frame-difference")
    error = page.locator("#toasts .toast-error")
    error.first.wait_for(timeout=10000)
    text = error.first.inner_text()
    assert "Server unreachable: try again when it is back" in text, text
    assert "Failed to fetch" not in text
    assert method.input_value() == "adaptive"  # Back to the method in force.


def test_a_hidden_page_watches_no_camera_and_gets_no_frame_till_shown(
    serve: Callable[..., Running], page: Any, motion_video: Path
) -> None:
    # A tab in the background asks for no picture: it unwatches every camera on /ws/live
    # (the server sends it no frame), and closes an analysis's MJPEG stream, which with
    # the ~6 connections a browser allows a host across all tabs locked up a new tab.
    server = serve()
    frames: list[float] = []
    page.on(
        "websocket",
        lambda socket: (
            socket.on("framereceived", lambda _: frames.append(time.monotonic()))
            if socket.url.endswith("/ws/live")
            else None
        ),
    )
    ids = show_cameras(server, page, f"file://{motion_video}", 2)
    cameras = server.server.config.app.state.services.cameras
    hubs = [cameras.get(cam).hub for cam in ids]
    assert all(hub.watching["live"] == 1 for hub in hubs)
    set_hidden(page, True)
    wait_for(lambda: all(hub.watching["live"] == 0 for hub in hubs), 5, "the cameras unwatched")
    # An analysis watched live meanwhile opens no stream either.
    watch_analysis_live(server, page)
    page.wait_for_timeout(300)  # A frame already on its way may still come.
    hidden_at = time.monotonic()
    drawn = page.evaluate("[...document.querySelectorAll('canvas.live')].map(c => c.dataset.drawn)")
    page.wait_for_timeout(2500)
    assert [t for t in frames if t > hidden_at] == [], "frames came to a hidden page"
    assert page.evaluate(STREAMS_OPEN) == 0
    assert drawn == page.evaluate(
        "[...document.querySelectorAll('canvas.live')].map(c => c.dataset.drawn)"
    )
    set_hidden(page, False)
    wait_for(lambda: all(hub.watching["live"] == 1 for hub in hubs), 10, "the cameras watched")
    assert page.evaluate(STREAMS_OPEN) == 1  # The analysis's.
    shown_at = time.monotonic()
    for _ in range(100):  # Playwright tells of frames only while it is waited on.
        if len([t for t in frames if t > shown_at]) > 20:
            break
        page.wait_for_timeout(100)
    assert len([t for t in frames if t > shown_at]) > 20, "no frames once shown"
    assert page.locator(".card img.broken").count() == 0


def test_select_all_says_what_is_ticked_when_snapshots_arrive(
    serve: Callable[..., Running], page: Any
) -> None:
    # "select all" stayed ticked while snapshots that came in after it came unticked:
    # "Delete selected" then skipped what the box claimed to cover.
    server = serve(demo_camera=True)
    cam = httpx.get(f"{server.base}/api/cameras").json()[0]["id"]
    first = [add_snapshot(server, cam, 1_800_000_000.0 + i) for i in range(2)]
    page.goto(server.base + "/")
    boxes = page.locator("#thumbs input")
    select_all = page.locator("#select-all")
    wait_for(lambda: boxes.count() == 2, 10, "two thumbnails")
    select_all.check()
    later = add_snapshot(server, cam, 1_800_000_010.0)
    publish(server, alarm(cam, 1, time.time()))  # An alarm's snapshot: the gallery lists it.
    wait_for(lambda: boxes.count() == 3, 10, "the new thumbnail")
    ticked = page.locator("#thumbs input:checked").evaluate_all("bs => bs.map(b => +b.value)")
    assert sorted(ticked) == first  # What was shown when it was ticked, not the newcomer.
    assert not select_all.is_checked()
    select_all.check()
    assert page.locator("#thumbs input:checked").count() == 3
    page.locator(f'#thumbs input[value="{later}"]').uncheck()
    assert not select_all.is_checked()
