"""Clips in a real Chromium: the Events view's timeline and player, a toast that opens its
event, and an upload's annotated.mp4 with its events as chapters."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.api.vigil_livekit import Running, WsClient, add_camera, wait_for, write_video

pytestmark = pytest.mark.browser

RECORDING = {"pre_roll_s": 1.0, "post_roll_s": 0.5, "quiet_s": 0.5}

PLAYS = """async (video) => {
  const wait = (test, ms) => new Promise((done, failed) => {
    const started = performance.now();
    const poll = () => test() ? done() : performance.now() - started > ms
      ? failed(new Error(`timed out: readyState ${video.readyState}, t ${video.currentTime}`))
      : setTimeout(poll, 50);
    poll();
  });
  await wait(() => video.readyState === 4, 15000);
  const duration = video.duration;
  video.pause();
  await new Promise((done) => { video.addEventListener("seeked", done, { once: true });
    video.currentTime = 0; });
  await video.play();
  await wait(() => video.currentTime > 0.3, 5000);
  const played = video.currentTime;
  video.pause();
  const target = Math.min(1.0, duration / 2);
  await new Promise((done) => { video.addEventListener("seeked", done, { once: true });
    video.currentTime = target; });
  return { duration, played, target, landed: video.currentTime, ready: video.readyState,
           width: video.videoWidth, error: video.error && video.error.message };
}"""


def _plays(page: Any, selector: str) -> dict[str, Any]:
    """Chromium plays the video: it reaches readyState 4, time goes on, a seek lands."""
    result: dict[str, Any] = page.locator(selector).evaluate(PLAYS)
    assert result["error"] is None and result["ready"] >= 2
    assert result["duration"] > 0.5 and result["played"] > 0.3, result
    assert result["landed"] == pytest.approx(result["target"], abs=0.05), result
    return result


def _recorded_events(server: Running, video: Path, count: int) -> tuple[int, list[int]]:
    """A camera that recorded ``count`` events, stopped (its activity written); their ids."""
    camera = add_camera(server.base, f"file://{video}", "door")
    with WsClient(server.ws) as ws:
        httpx.post(f"{server.base}/api/cameras/{camera}/activate").raise_for_status()
        ends = ws.wait("motion_end", 60, count=count, camera_id=camera)
        httpx.post(f"{server.base}/api/cameras/{camera}/stop").raise_for_status()
    ids = [m["event_id"] for m in ends[:count]]
    for event_id in ids:
        wait_for(
            lambda e=event_id: httpx.get(f"{server.base}/api/events/{e}").json()["clip_s"],
            10,
            f"event {event_id}'s clip",
        )
    return camera, ids


def test_the_events_view_shows_the_day_and_plays_an_events_clip(
    serve: Callable[..., Running], page: Any, tmp_path: Path
) -> None:
    server = serve(**RECORDING)
    camera, ids = _recorded_events(server, write_video(tmp_path / "door.avi", frames=75), 3)
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.goto(server.base + "/#events")
    strip = page.locator(f'.timeline[data-camera="{camera}"]')
    marks = strip.locator(".event-mark")
    wait_for(lambda: marks.count() >= 3, 15, "the events on the camera's timeline")
    assert strip.locator(".motion-area").count() >= 1, "the motion while it was activated"
    assert strip.locator(".unwatched").count() >= 1, "the rest of the day: not watched"

    # On a day, marks seconds apart overlap: a click picks the event nearest to it.
    mark, drawn = marks.first.bounding_box(), strip.locator("svg").bounding_box()
    spot = {"x": mark["x"] - drawn["x"] + mark["width"] / 2, "y": drawn["height"] / 2}
    strip.locator("svg").click(position=spot)
    player = page.locator(".event-player")
    player.wait_for(state="visible")
    shown = int(player.get_attribute("data-event"))
    assert shown in ids
    result = _plays(page, ".event-player video")
    assert result["width"] == 320
    event = httpx.get(f"{server.base}/api/events/{shown}").json()
    assert result["duration"] == pytest.approx(event["clip_s"], abs=0.1)
    page.wait_for_function(
        "() => document.querySelector('.event-snapshot').naturalWidth > 0", timeout=5000
    )
    assert "door" in player.locator(".event-facts").inner_text()

    player.get_by_role("button", name="Previous event").click()
    wait_for(lambda: int(player.get_attribute("data-event")) < shown, 5, "the event before")
    previous = int(player.get_attribute("data-event"))
    player.get_by_role("button", name="Next event").click()
    wait_for(lambda: int(player.get_attribute("data-event")) == shown, 5, "back to the next")
    assert previous in ids

    # Zoom to the events' hour: the same marks, wider.
    page.select_option("#events-filter select[name=hour]", str(_hour(page, event)))
    wait_for(lambda: marks.count() >= 3, 10, "the hour's events")
    assert page.evaluate("window.__csp") == []
    assert errors == []


def _hour(page: Any, event: dict[str, Any]) -> int:
    return int(page.evaluate("(ts) => new Date(ts * 1000).getHours()", event["started_at"]))


def test_an_alarms_toast_opens_its_event_in_the_events_view(
    serve: Callable[..., Running], page: Any, tmp_path: Path
) -> None:
    server = serve(**RECORDING)
    video = write_video(tmp_path / "door.avi", frames=75)
    camera = add_camera(server.base, f"file://{video}", "door")
    page.goto(server.base + "/")
    page.wait_for_selector(f'.card[data-id="{camera}"]')
    httpx.post(f"{server.base}/api/cameras/{camera}/activate").raise_for_status()
    link = page.locator("#toasts .toast .open-event").first
    link.wait_for(timeout=30000)
    event_id = int(link.get_attribute("data-event"))
    link.click()
    player = page.locator(".event-player")
    player.wait_for(state="visible")
    assert int(player.get_attribute("data-event")) == event_id
    # While it records, the clip plays as far as it has got; once written, whole.
    wait_for(
        lambda: "recording" not in player.locator(".event-facts").inner_text(),
        20,
        "the clip to be written, as the view hears",
    )
    event = httpx.get(f"{server.base}/api/events/{event_id}").json()
    result = _plays(page, ".event-player video")
    assert result["duration"] == pytest.approx(event["clip_s"], abs=0.1)
    assert page.evaluate("window.__csp") == []


def test_an_uploads_annotated_mp4_plays_with_its_events_as_chapters(
    serve: Callable[..., Running], page: Any, tmp_path: Path
) -> None:
    server = serve()
    page.goto(server.base + "/")
    video = write_video(tmp_path / "upload.avi", frames=90)
    page.set_input_files("#upload input[type=file]", str(video))
    page.click("#upload button[type=submit]")
    page.wait_for_selector(".analysis .status.badge-done", timeout=60000)
    panel = page.locator(".analysis").first
    result = _plays(page, ".analysis video.annotated")
    assert result["duration"] == pytest.approx(90 / 15, abs=0.1)
    chapters = panel.locator(".chapter")
    assert chapters.count() >= 1
    at = float(chapters.last.get_attribute("data-at"))
    chapters.last.click()
    page.wait_for_function(
        f"() => Math.abs(document.querySelector('.analysis video').currentTime - {at}) < 0.3"
        " || document.querySelector('.analysis video').currentTime > " + str(at),
        timeout=5000,
    )
    assert page.evaluate("window.__csp") == []
