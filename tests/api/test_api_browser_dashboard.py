"""The dashboard in a real Chromium (Playwright), as an outside audit used it.

A server restart under the page, an alarm flood, sound before the first click, a phone's
width, the alarm list across events and reloads, a deleted camera's snapshots, many
cameras, a camera that goes away.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.api.vigil_livekit import (
    MjpegCamera,
    Running,
    add_camera,
    free_port,
    hold_answers,
    live_settings,
    running_server,
    show_cameras,
    wait_for,
    wait_for_pictures,
)

pytestmark = pytest.mark.browser

LISTING = re.compile(r"/api/cameras$")
"""The camera listing's URL, whose answers the tests hold back."""

PICTURE_HASHES = """(selector) => [...document.querySelectorAll(selector)].map((img) => {
  // No frame (yet): blank, loading or broken.
  if (img.tagName === 'CANVAS' ? !Number(img.dataset.drawn) : !img.naturalWidth) return null;
  const canvas = document.createElement('canvas');
  canvas.width = 64; canvas.height = 48;
  const context = canvas.getContext('2d');
  try { context.drawImage(img, 0, 0, 64, 48); } catch (e) { return null; }
  const data = context.getImageData(0, 0, 64, 48).data;
  let hash = 0;
  for (let i = 0; i < data.length; i += 3) hash = (hash * 31 + data[i]) >>> 0;
  return hash;
})"""


def pictures_move(
    page: Any, selector: str = ".card canvas.live", seconds: float = 4.0
) -> list[bool]:
    """Whether each picture showed more than one frame in ``seconds`` (a blank or broken
    picture is no frame: going from blank to one frame is no movement)."""
    seen: list[set[int]] = []
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        hashes = page.evaluate(PICTURE_HASHES, selector)
        seen = seen or [set() for _ in hashes]
        for known, value in zip(seen, hashes, strict=True):
            if value is not None:
                known.add(value)
        page.wait_for_timeout(200)
    return [len(known) > 1 for known in seen]


def publish(server: Running, message: dict[str, Any]) -> None:
    """A message on the server's /ws, as a camera worker sends it."""
    server.server.config.app.state.services.bus.publish(message)


def alarm(camera_id: int, event_id: int, ts: float, name: str = "yard") -> dict[str, Any]:
    return {
        "type": "alarm",
        "camera_id": camera_id,
        "camera_name": name,
        "event_id": event_id,
        "ts": ts,
        "frame": 1,
        "boxes": [[10, 20, 30, 40]],
        "objects": [{"track_id": 1, "box": [10, 20, 30, 40], "area": 1200.0, "speed_px_s": 5.0}],
        "snapshot": None,
        "snapshot_id": None,
        "difference": None,
    }


def test_pictures_come_back_after_a_server_restart_and_cards_say_when_it_is_away(
    page: Any, motion_video: Path, tmp_path: Path
) -> None:
    port = free_port()
    settings = live_settings(tmp_path / "data")
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    with running_server(settings, port, graceful_s=1) as server:
        add_camera(server.base, f"file://{motion_video}", name="lane")
        add_camera(server.base, f"file://{motion_video}", name="road")
        page.goto(server.base + "/")
        wait_for_pictures(page, 2, timeout_ms=20000)
        assert all(pictures_move(page))
    # The server is away: no card claims to be live, none shows a frame rate.
    page.wait_for_function(
        "() => [...document.querySelectorAll('.card .state')]"
        ".every(b => b.textContent === 'server unreachable')",
        timeout=10000,
    )
    assert page.locator(".card .fps").all_inner_texts() == ["", ""]
    assert page.locator(".card.stale").count() == 2
    with running_server(settings, port, graceful_s=1):
        page.wait_for_function(
            "() => [...document.querySelectorAll('.card .state')]"
            ".every(b => b.textContent === 'live')",
            timeout=20000,
        )
        # The MJPEG streams ended with the old server: the page opened them again.
        wait_for(lambda: all(pictures_move(page, seconds=2.0)), 15, "the pictures to move again")
        assert page.locator(".card.stale").count() == 0
        assert "fps" in page.locator(".card .fps").first.inner_text()
    assert errors == []


def test_alarm_toasts_are_capped_and_repeats_of_an_event_merge(
    serve: Callable[..., Running], page: Any
) -> None:
    server = serve()
    page.goto(server.base + "/")
    page.wait_for_selector("#ws-state.badge-live", timeout=10000)
    now = time.time()
    for event_id in range(1, 11):  # Ten events on ten cameras at once.
        publish(server, alarm(event_id, event_id, now + event_id * 0.01, name=f"cam{event_id}"))
    page.wait_for_function("() => document.querySelectorAll('#toasts .toast').length === 10")
    visible = page.locator("#toasts .toast:visible")
    assert visible.count() == 3
    assert "cam10" in visible.first.inner_text(), "newest first"
    assert page.locator("#toasts-more").inner_text().startswith("+7 more")
    column = page.evaluate("document.getElementById('toasts').getBoundingClientRect().height")
    assert column < 450, column
    # Between the toasts, clicks reach the page below.
    assert page.evaluate(
        "(() => { const [a, b] = [...document.querySelectorAll('#toasts .toast')]"
        ".filter(t => !t.hidden).map(t => t.getBoundingClientRect());"
        " if (!(b.top - a.bottom > 2)) return false;"
        " const e = document.elementFromPoint(a.left + a.width / 2, (a.bottom + b.top) / 2);"
        " return !document.querySelector('#toasts').contains(e); })()"
    )

    # Five more alarms of event 3: one toast, updated, on top; one list entry.
    for i in range(5):
        publish(server, alarm(3, 3, now + 1 + i, name="cam3"))
    page.wait_for_function(
        "() => document.querySelector('#toasts .toast').textContent.includes('×6')"
    )
    assert page.locator("#toasts .toast").count() == 10
    assert page.locator('#alarm-list li[data-event="3"]').count() == 1

    page.click("#toasts-dismiss")
    page.wait_for_function("() => document.querySelectorAll('#toasts .toast').length === 0")
    assert page.locator("#toasts-more").is_hidden()


# The card's flash: how far into it the card is (ms), or null when it is not flashing.
FLASHING = """id => {
  const card = document.querySelector(`.card[data-id="${id}"]`);
  const flash = card.getAnimations().find(a => a.animationName === 'flash');
  return flash && card.classList.contains('flash') ? flash.currentTime : null;
}"""


def test_a_card_flashes_at_each_alarm_and_an_alarm_during_the_flash_starts_it_again(
    serve: Callable[..., Running], page: Any, motion_video: Path
) -> None:
    server = serve()
    cam = add_camera(server.base, f"file://{motion_video}", name="lane")
    page.goto(server.base + "/")
    page.wait_for_selector("#ws-state.badge-live", timeout=10000)
    assert page.evaluate(FLASHING, cam) is None
    publish(server, alarm(cam, 1, time.time(), name="lane"))
    page.wait_for_function(f"() => ({FLASHING})({cam}) !== null")
    page.wait_for_function(f"() => ({FLASHING})({cam}) > 700")
    publish(server, alarm(cam, 1, time.time(), name="lane"))  # The same event's next alarm.
    page.wait_for_function(f"() => ({FLASHING})({cam}) < 500")
    # It ends (1.2 s), and the next event's alarm flashes the card again.
    page.wait_for_function(f"() => ({FLASHING})({cam}) === null", timeout=5000)
    publish(server, alarm(cam, 2, time.time(), name="lane"))
    page.wait_for_function(f"() => ({FLASHING})({cam}) !== null")


def test_sound_waits_for_a_click_and_says_so(serve: Callable[..., Running], page: Any) -> None:
    server = serve()
    page.add_init_script(
        "window.__oscillators = 0;"
        "const make = AudioContext.prototype.createOscillator;"
        "AudioContext.prototype.createOscillator = function () {"
        " window.__oscillators++; return make.call(this); };"
    )
    page.goto(server.base + "/")
    page.wait_for_selector("#ws-state.badge-live", timeout=10000)
    mute = page.locator("#mute")
    # No emoji (a box without emoji fonts): an inline SVG icon.
    assert mute.locator("svg").count() == 1 and "🔔" not in mute.inner_text()
    assert "click to enable sound" in mute.inner_text().lower()
    publish(server, alarm(1, 1, time.time()))
    page.wait_for_selector("#alarm-list li")
    assert page.evaluate("window.__oscillators") == 0

    # A click on the button itself enables sound (and does not mute it).
    mute.click()
    page.wait_for_function("() => document.getElementById('mute').textContent.includes('Sound on')")
    assert mute.get_attribute("aria-pressed") == "false"
    publish(server, alarm(1, 2, time.time()))
    page.wait_for_function("() => window.__oscillators > 0")
    mute.click()
    assert "Sound off" in mute.inner_text() and mute.get_attribute("aria-pressed") == "true"


def test_sound_unlocked_by_a_key_or_a_press_dragged_off_the_button_still_mutes_on_click(
    serve: Callable[..., Running], page: Any
) -> None:
    server = serve()
    sound_on = "() => document.getElementById('mute').textContent.includes('Sound on')"
    mute = page.locator("#mute")
    # Tab away from the focused button unlocks sound (a key press); the next click mutes.
    page.goto(server.base + "/")
    page.wait_for_selector("#ws-state.badge-live", timeout=10000)
    assert "click to enable sound" in mute.inner_text().lower()
    mute.focus()
    page.keyboard.press("Tab")
    page.wait_for_function(sound_on)
    mute.click()
    assert "Sound off" in mute.inner_text() and mute.get_attribute("aria-pressed") == "true"
    mute.click()
    assert "Sound on" in mute.inner_text()

    # A press on the button released elsewhere unlocks sound without a click on it; the
    # next click mutes.
    page.evaluate("localStorage.removeItem('vigil.muted')")
    page.reload()
    page.wait_for_selector("#ws-state.badge-live", timeout=10000)
    assert "click to enable sound" in mute.inner_text().lower()
    box = mute.bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + 300, steps=5)
    page.mouse.up()
    page.wait_for_function(sound_on)
    mute.click()
    assert "Sound off" in mute.inner_text() and mute.get_attribute("aria-pressed") == "true"

    # Enter on the focused button that asks for sound enables it and does not mute.
    page.evaluate("localStorage.removeItem('vigil.muted')")
    page.reload()
    page.wait_for_selector("#ws-state.badge-live", timeout=10000)
    mute.focus()
    page.keyboard.press("Enter")
    page.wait_for_function(sound_on)
    page.wait_for_timeout(300)
    assert mute.get_attribute("aria-pressed") == "false"


def test_dashboard_fits_a_phone(
    serve: Callable[..., Running], page: Any, motion_video: Path
) -> None:
    server = serve()
    add_camera(server.base, f"file://{motion_video}", name="lane")
    page.set_viewport_size({"width": 390, "height": 844})
    page.goto(server.base + "/")
    wait_for_pictures(page, 1, timeout_ms=20000)
    page.wait_for_timeout(1500)  # The motion chart is drawn.
    sizes = page.evaluate(
        "({ scroll: document.documentElement.scrollWidth,"
        " client: document.documentElement.clientWidth,"
        " mute: document.getElementById('mute').getBoundingClientRect().right,"
        " badge: document.getElementById('ws-state').getBoundingClientRect().right,"
        " card: document.querySelector('.card').getBoundingClientRect().right })"
    )
    assert sizes["scroll"] <= sizes["client"] == 390, sizes
    for name in ("mute", "badge", "card"):
        assert sizes[name] <= 390, sizes


def test_alarm_list_one_entry_per_event_kept_across_reloads_and_deleted_cameras_filtered(
    serve: Callable[..., Running], page: Any, motion_video: Path
) -> None:
    server = serve()
    base = server.base
    page.goto(base + "/")
    page.wait_for_selector("#ws-state.badge-live", timeout=10000)
    # Two alarms of one event, then its end: one entry, not moving any more.
    now = time.time()
    publish(server, alarm(7, 900, now))
    publish(server, alarm(7, 900, now + 1))
    publish(
        server,
        {"type": "motion_end", "camera_id": 7, "event_id": 900, "ts": now + 2,
         "duration_s": 2.0, "max_area": 1200.0},
    )  # fmt: skip
    page.wait_for_function(
        "() => document.querySelector('#alarm-list li .ongoing')?.textContent.startsWith('ended')"
    )
    assert page.locator("#alarm-list li").count() == 1
    assert "moving" not in page.locator("#alarm-list").inner_text()

    # A real camera alarms, is stopped and deleted; its event and snapshots stay.
    lane = add_camera(base, f"file://{motion_video}", name="lane", activate=True)
    wait_for(lambda: httpx.get(f"{base}/api/events").json(), 30, "an event")
    httpx.post(f"{base}/api/cameras/{lane}/stop").raise_for_status()
    wait_for(
        lambda: all(e["ended_at"] for e in httpx.get(f"{base}/api/events").json()),
        15,
        "the event to end",
    )
    httpx.delete(f"{base}/api/cameras/{lane}").raise_for_status()

    page.reload()
    entry = page.locator(f'#alarm-list li[data-camera="{lane}"]').first
    entry.wait_for(timeout=10000)
    assert f"camera {lane} (deleted)" in entry.inner_text()
    assert "ended after" in entry.inner_text()
    assert entry.locator("img").count() == 1, "the event's snapshot"
    option = page.locator(
        f'#gallery-filter select[name=camera_id] option[value="{lane}"]'
    ).inner_text()
    assert option == f"camera {lane} (deleted)"
    page.select_option("#gallery-filter select[name=camera_id]", str(lane))
    page.click("#gallery-filter button[type=submit]")
    page.wait_for_selector("#thumbs figure", timeout=10000)
    assert f"camera {lane} (deleted)" in page.locator("#thumbs figcaption").first.inner_text()

    # "Clear list" holds across a reload.
    page.click("#clear-alarms")
    with page.expect_response(lambda r: "/api/events?" in r.url):
        page.reload()
    page.wait_for_selector("#ws-state.badge-live", timeout=10000)
    page.wait_for_timeout(1000)
    assert page.locator("#alarm-list li").count() == 0


SKEWED_CLOCK = """(() => {
  // The browser's clock off by sessionStorage['test.skew'] seconds (kept across reloads).
  const skew = Number(sessionStorage.getItem('test.skew') || 0) * 1000;
  const Real = Date;
  class Skewed extends Real {
    constructor(...args) { if (args.length) super(...args); else super(Real.now() + skew); }
    static now() { return Real.now() + skew; }
  }
  window.Date = Skewed;
})();"""


def test_clear_list_holds_across_reloads_with_the_browser_clock_an_hour_off(
    serve: Callable[..., Running], page: Any
) -> None:
    server = serve()
    db = server.server.config.app.state.services.database

    def event(started_at: float) -> int:
        return db.add_event(7, started_at, [[10, 20, 30, 40]], 1200.0)

    def shown_events() -> list[str]:
        with page.expect_response(lambda r: "/api/events?" in r.url):
            page.reload()
        page.wait_for_selector("#ws-state.badge-live", timeout=10000)
        page.wait_for_timeout(1000)  # The recent events are listed.
        return page.locator("#alarm-list li").evaluate_all("li => li.map(i => i.dataset.event)")

    page.add_init_script(SKEWED_CLOCK)
    page.goto(server.base + "/")
    # The browser's clock is an hour behind the server's.
    page.evaluate("sessionStorage.setItem('test.skew', '-3600')")
    event(time.time() - 60)
    event(time.time() - 30)
    assert len(shown_events()) == 2
    started = time.time()
    live = event(started)
    publish(server, alarm(7, live, started))
    page.wait_for_function("() => document.querySelectorAll('#alarm-list li').length === 3")
    page.click("#clear-alarms")
    assert shown_events() == [], "cleared events came back"

    # An hour ahead: a new event shows after a reload, also once the list was cleared.
    page.evaluate("sessionStorage.setItem('test.skew', '3600')")
    first = event(time.time())
    assert shown_events() == [str(first)]
    page.click("#clear-alarms")
    second = event(time.time())
    assert shown_events() == [str(second)], "a new event hidden"


def test_only_the_cameras_on_screen_are_watched_and_at_their_rate(
    serve: Callable[..., Running], page: Any, motion_video: Path
) -> None:
    server = serve()
    page.set_viewport_size({"width": 1280, "height": 800})  # Two cards a row, two rows seen.
    ids = show_cameras(server, page, f"file://{motion_video}", 6)
    hubs = {cam: server.server.config.app.state.services.cameras.get(cam).hub for cam in ids}

    def on_screen() -> set[int]:
        return set(
            page.evaluate(
                "[...document.querySelectorAll('.card')].filter(card => {"
                " const box = card.querySelector('.picture').getBoundingClientRect();"
                " return box.bottom > 0 && box.top < innerHeight; }).map(c => Number(c.dataset.id))"
            )
        )

    # The page goes on below the cameras (events, notifications, uploads): the second
    # position puts the last card at the bottom of the window, not the page's end.
    last_card = "[...document.querySelectorAll('.card')].pop().scrollIntoView({block: 'end'})"
    for scrolled in ("window.scrollTo(0, 0)", last_card):
        page.evaluate(scrolled)
        shown = on_screen()
        assert 0 < len(shown) < len(ids), shown
        wait_for(
            lambda shown=shown: all(
                hub.watching["live"] == (1 if cam in shown else 0) for cam, hub in hubs.items()
            ),
            5,
            f"cameras {sorted(shown)} watched, and only those",
        )
    # Those shown are drawn at their camera's rate (the clip's 15 fps).
    drawn = "c => Number(c.dataset.drawn)"
    cam = sorted(shown)[-1]
    canvas = page.locator(f'.card[data-id="{cam}"] canvas.live')
    before = canvas.evaluate(drawn)
    page.wait_for_timeout(4000)
    rate = (canvas.evaluate(drawn) - before) / 4
    assert rate >= 10, f"{rate:.1f} frames a second drawn"
    assert "shown/s" in page.locator(f'.card[data-id="{cam}"] .fps').inner_text()


def test_a_camera_that_goes_away_asks_for_no_pictures_meanwhile(
    serve: Callable[..., Running], page: Any
) -> None:
    camera = MjpegCamera().start()
    try:
        server = serve()
        cam = add_camera(server.base, camera.url, name="door")
        page.goto(server.base + "/")
        wait_for_pictures(page, 1, timeout_ms=20000)
        page.wait_for_function(
            "() => document.querySelector('.card img.histogram').naturalWidth > 0", timeout=10000
        )
        camera.stop()
        card = page.locator(f'.card[data-id="{cam}"]')
        wait_for(
            lambda: card.locator(".state").inner_text() in ("reconnecting", "error"),
            20,
            "the camera to be lost",
        )
        refused: list[str] = []
        page.on("response", lambda r: refused.append(r.url) if r.status == 503 else None)
        page.wait_for_timeout(4000)
        # A failed picture is hidden (img.broken, so no broken-image icon): the card
        # keeps its last picture and histogram in view instead of going blank. (Playwright
        # never counts a `visibility: hidden` element as visible, so ask for the class.)
        broken = card.locator("img.broken").evaluate_all("imgs => imgs.map(i => i.className)")
        assert broken == [], "pictures blanked by failed requests"
        assert card.locator("canvas.live").is_visible()
        assert card.locator("img.histogram").is_visible()
        assert card.locator("img.histogram").evaluate("i => i.naturalWidth") > 0
        # It asked for a histogram every second, each a 503 in the console.
        assert refused == []
    finally:
        camera.stop()


def test_a_setting_ticked_on_the_page_holds_while_the_server_answers(
    serve: Callable[..., Running], page: Any
) -> None:
    # A camera's status message that came before the PATCH's answer redrew the card from
    # the settings as they were, and unticked "auto" just ticked (a flaky browser test
    # showed it). The answer is held here while a status message arrives.
    server = serve(demo_camera=True)
    cam = httpx.get(f"{server.base}/api/cameras").json()[0]["id"]
    httpx.patch(f"{server.base}/api/cameras/{cam}", json={"sensitivity": 40}).raise_for_status()
    page.goto(server.base + "/")
    auto = page.locator(f'.card[data-id="{cam}"] input.auto')
    wait_for(lambda: auto.count() and not auto.is_checked(), 20, "the card at sensitivity 40")
    held: list[Any] = []
    page.route(
        f"**/api/cameras/{cam}",
        lambda route: held.append(route) if route.request.method == "PATCH" else route.continue_(),
    )
    auto.check()
    # The page's waits are what let the route handler run.
    wait_for(lambda: held or page.wait_for_timeout(50), 10, "the PATCH to be sent")
    status = httpx.get(f"{server.base}/api/cameras/{cam}").json()
    publish(server, {"type": "status", "camera_id": cam, "state": status["state"], "fps": 15.0})
    page.wait_for_timeout(1500)  # The status message above, and the camera's own.
    assert auto.is_checked()
    held[0].continue_()
    wait_for(
        lambda: httpx.get(f"{server.base}/api/cameras/{cam}").json()["sensitivity"] is None,
        10,
        "automatic sensitivity on the server",
    )
    assert auto.is_checked()


def test_a_camera_listing_answered_late_does_not_undo_a_newer_state(
    serve: Callable[..., Running], page: Any
) -> None:
    # The page asks for the camera list when /ws tells of a camera it does not know. An
    # answer that came after a status message put back the state from before it: a lost
    # camera showed "live" until the next listing, 15 s on (a flaky browser test showed
    # a live camera as "connecting"). The listing's answer is held here while it goes.
    camera = MjpegCamera().start()
    try:
        # No retry, so no new status message, for 5 s after the camera is lost.
        server = serve(reconnect_min_s=5.0, reconnect_max_s=5.0)
        door = add_camera(server.base, camera.url, name="door")
        page.goto(server.base + "/")
        badge = page.locator(f'.card[data-id="{door}"] .state')
        wait_for(lambda: badge.inner_text() == "live", 20, "the camera to be live")
        held = hold_answers(page, LISTING)  # Answered now (the camera is live).
        add_camera(server.base, camera.url, name="yard")
        wait_for(lambda: held or page.wait_for_timeout(50), 10, "the page to list the cameras")
        camera.stop()
        wait_for(lambda: badge.inner_text() != "live", 20, "the camera to be lost")
        lost = badge.inner_text()
        # The listing asked for while the camera was live comes now; the others wait, so
        # none can put things right.
        first, answer = held.pop(0)
        first.fulfill(response=answer)
        page.wait_for_timeout(1000)
        assert badge.inner_text() == lost
        for route, answer in held:
            route.fulfill(response=answer)
        page.unroute(LISTING)
        page.wait_for_selector(".card .cam-name >> text=yard", timeout=10000)
        assert badge.inner_text() == lost
    finally:
        camera.stop()


def test_a_settings_answer_that_comes_late_does_not_undo_a_newer_state(
    serve: Callable[..., Running], page: Any
) -> None:
    # A PATCH's answer holds the camera's state when it was answered: given to the page
    # after a status message said the camera was lost, it showed the camera live again.
    camera = MjpegCamera().start()
    try:
        server = serve(reconnect_min_s=5.0, reconnect_max_s=5.0)  # No status for 5 s.
        door = add_camera(server.base, camera.url, name="door")
        page.goto(server.base + "/")
        card = page.locator(f'.card[data-id="{door}"]')
        wait_for(lambda: card.locator(".state").inner_text() == "live", 20, "the camera live")
        answer_to_patch = re.compile(rf"/api/cameras/{door}$")
        held = hold_answers(page, answer_to_patch, "PATCH")
        card.locator(".method").select_option("frame-difference")
        wait_for(lambda: held or page.wait_for_timeout(50), 10, "the PATCH to be answered")
        camera.stop()
        wait_for(lambda: card.locator(".state").inner_text() != "live", 20, "the camera lost")
        lost = card.locator(".state").inner_text()
        route, answer = held.pop(0)
        route.fulfill(response=answer)
        page.unroute(answer_to_patch)
        page.wait_for_timeout(1000)
        assert card.locator(".state").inner_text() == lost
        assert card.locator(".method").input_value() == "frame-difference"
    finally:
        camera.stop()


def open_demo_card(serve: Callable[..., Running], page: Any) -> tuple[Running, int, Any]:
    """A server with its demo camera, and the page open on it: the server, the camera's id
    and its card (a locator: the card may not be drawn yet)."""
    server = serve(demo_camera=True)
    cam = httpx.get(f"{server.base}/api/cameras").json()[0]["id"]
    page.goto(server.base + "/")
    return server, cam, page.locator(f'.card[data-id="{cam}"]')


def test_a_listing_asked_for_before_a_change_does_not_undo_it(
    serve: Callable[..., Running], page: Any
) -> None:
    # Settings come in no status message: a listing asked for before the method was
    # changed, answered after, showed the old method until the next listing (15 s).
    server, demo, card = open_demo_card(serve, page)
    method = card.locator(".method")
    wait_for(lambda: method.count() and method.input_value() == "adaptive", 20, "the card")
    held = hold_answers(page, LISTING)
    add_camera(server.base, "demo", name="yard")  # The page asks for the list.
    wait_for(lambda: held or page.wait_for_timeout(50), 10, "the page to list the cameras")
    method.select_option("frame-difference")
    wait_for(
        lambda: (
            httpx.get(f"{server.base}/api/cameras/{demo}").json()["method"] == "frame-difference"
        ),
        10,
        "the method changed on the server",
    )
    for route, answer in held:
        route.fulfill(response=answer)
    page.unroute(LISTING)
    page.wait_for_selector(".card .cam-name >> text=yard", timeout=10000)
    page.wait_for_timeout(500)
    assert method.input_value() == "frame-difference"


def test_an_alarm_open_when_the_server_restarts_shows_its_end_after(
    page: Any, motion_video: Path, tmp_path: Path
) -> None:
    # A restart ends the open event in the database, but no motion_end reaches a page:
    # its entry said "moving…" until the page was reloaded.
    port = free_port()
    settings = live_settings(tmp_path / "data", quiet_s=30.0)  # Open until the restart.
    with running_server(settings, port, graceful_s=1) as server:
        add_camera(server.base, f"file://{motion_video}", name="lane", activate=True)
        page.goto(server.base + "/")
        page.wait_for_selector("#alarm-list li", timeout=20000)
        entry = page.locator("#alarm-list li").first
        event = entry.get_attribute("data-event")
        assert entry.locator(".ongoing").inner_text() == "moving…"
    with running_server(settings, port, graceful_s=1):
        shown = page.locator(f'#alarm-list li[data-event="{event}"] .ongoing')
        wait_for(lambda: shown.inner_text().startswith("ended after"), 20, "the alarm's end")


def test_a_change_made_elsewhere_shows_on_an_open_page_at_once(
    serve: Callable[..., Running], page: Any
) -> None:
    # A PATCH from a script or another tab reached an open page at its next listing of
    # the cameras, up to 15 s on: "auto (33)" with the slider where it was (live audit).
    server, cam, card = open_demo_card(serve, page)
    wait_for(lambda: card.locator(".state").inner_text() == "live", 20, "the card")
    changed = {"sensitivity": 33, "name": "porch", "method": "frame-difference"}
    httpx.patch(f"{server.base}/api/cameras/{cam}", json=changed).raise_for_status()
    wait_for(lambda: card.locator(".cam-name").inner_text() == "porch", 3, "the new name")
    assert card.locator(".sens-value").inner_text() == "33"
    assert not card.locator("input.auto").is_checked()
    assert card.locator(".method").input_value() == "frame-difference"
