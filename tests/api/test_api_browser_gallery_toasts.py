"""The dashboard in a real Chromium (Playwright), from a review: toasts over a card's
controls while alarms keep coming, a snapshot deleted in another tab shown as a broken
picture, and an alarm that listed the whole gallery again for one new snapshot."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

import httpx
import pytest

from tests.api.test_api_browser_dashboard import alarm, publish
from tests.api.test_api_browser_editing import open_page, overlaps, thumbnail_ids, zipped_ids
from tests.api.vigil_livekit import Running, add_camera, add_snapshot, wait_for, wait_for_pictures

pytestmark = pytest.mark.browser

BROKEN = "imgs => imgs.filter(i => !i.naturalWidth && getComputedStyle(i).visibility !== 'hidden')"
"""Of the pictures given, those that show the browser's broken-picture icon."""

T0 = 1_800_000_000.0

COVERED = """(el) => {
  const box = el.getBoundingClientRect();
  const covered = [];
  for (const fx of [0, 0.5, 1]) {
    for (const fy of [0.15, 0.5, 0.85]) {
      const x = box.left + Math.min(box.width - 2, Math.max(2, box.width * fx));
      const hit = document.elementFromPoint(x, box.top + box.height * fy);
      if (hit === null || !el.contains(hit)) covered.push([fx, fy, hit && hit.className]);
    }
  }
  return covered;
}"""
"""The points of an element (its corners, edges' middles and centre, just inside) where a
click, as the page lies now, does not reach it: Playwright's own click would scroll it
out from under a toast (and a point in a gap between two toasts is no proof)."""


def test_at_1280x800_the_toasts_leave_the_right_card_s_stop_and_slider_free(
    serve: Callable[..., Running], page: Any, motion_video: Path
) -> None:
    server = serve(quiet_s=30.0)  # Each camera's event stays open: its alarms keep coming.
    page.set_viewport_size({"width": 1280, "height": 800})
    cams = [
        add_camera(server.base, f"file://{motion_video}", name=f"cam{i}", activate=True)
        for i in range(2)
    ]
    page.goto(server.base + "/")
    wait_for_pictures(page, 2)
    shot = add_snapshot(server, cams[1], time.time())
    now = time.time()
    for i in range(4):  # Other cameras alarm too: a full stack, with "+N more".
        message = alarm(900 + i, 900 + i, now + i * 0.01, name=f"gate{i}")
        message["snapshot"] = f"/api/snapshots/{shot}.jpg"
        publish(server, message)
    page.wait_for_function("() => document.querySelectorAll('#toasts .toast').length >= 5")
    page.wait_for_timeout(300)  # Their snapshots load.
    assert page.locator("#toasts-more").is_visible()

    left, right = (page.locator(f'.card[data-id="{cam}"]') for cam in cams)
    assert right.bounding_box()["x"] > left.bounding_box()["x"] + 300, "not side by side"
    # The stack does lie over the right card (so what follows means something).
    assert overlaps(page.locator("#toasts").bounding_box(), right.bounding_box())
    stop, slider = right.locator(".toggle"), right.locator("input.sensitivity")
    assert stop.inner_text() == "Stop"
    for control in (stop, slider):
        assert control.evaluate(COVERED) == [], f"{control} is under a toast"

    # The slider's far end (the least sensitive) by a click there, as the page lies.
    box = slider.bounding_box()
    page.mouse.click(box["x"] + box["width"] - 2, box["y"] + box["height"] / 2)
    wait_for(
        lambda: (
            (httpx.get(f"{server.base}/api/cameras/{cams[1]}").json()["sensitivity"] or 0) >= 240
        ),
        10,
        "the sensitivity set from the slider's end",
    )
    stop.click()  # Playwright's click, with its checks that nothing covers it.
    wait_for(
        lambda: not httpx.get(f"{server.base}/api/cameras/{cams[1]}").json()["active"],
        10,
        "the camera to stop",
    )


def test_a_closed_alarm_toast_stays_closed_while_its_event_keeps_alarming(
    serve: Callable[..., Running], page: Any
) -> None:
    # An event alarms again every second while it goes on: a toast closed to reach what it
    # covered came back at the next alarm.
    server = serve()
    open_page(server, page)
    toasts = page.locator("#toasts .toast")
    now = time.time()
    for i in range(3):
        publish(server, alarm(10 + i, 100 + i, now + i * 0.01, name=f"cam{i}"))
    wait_for(lambda: toasts.count() == 3, 10, "three toasts")

    def again(step: float) -> None:
        """Each event alarms once more; waits until the page has heard them all."""
        for i in range(3):
            publish(server, alarm(10 + i, 100 + i, now + step + i * 0.01, name=f"cam{i}"))
        counts = [page.locator(f'#alarm-list li[data-event="{100 + i}"] .alarms') for i in range(3)]
        wait_for(
            lambda: all(f"({int(step) + 1} alarms" in c.inner_text() for c in counts),
            10,
            "the alarm list to count them",
        )

    # Its close button, then Escape (the newest): neither comes back with its next alarm.
    assert "cam2" in toasts.first.inner_text()
    toasts.first.get_by_role("button", name="close this message").click()
    wait_for(lambda: toasts.count() == 2, 5, "the toast closed")
    page.keyboard.press("Escape")
    wait_for(lambda: toasts.count() == 1, 5, "the newest closed by Escape")
    again(1)
    assert toasts.count() == 1 and "cam0" in toasts.first.inner_text()
    assert "×2" in toasts.first.inner_text()  # The one left open is updated.

    # "Dismiss all" alike; a new event of the same camera is news again.
    for i in range(3):  # Beyond the three shown: "+N more" and its "Dismiss all".
        publish(server, alarm(20 + i, 200 + i, now + 1.5 + i * 0.01, name=f"gate{i}"))
    wait_for(lambda: toasts.count() == 4, 10, "the new events' toasts")
    page.click("#toasts-dismiss")
    wait_for(lambda: toasts.count() == 0, 5, "all dismissed")
    again(2)
    assert toasts.count() == 0
    publish(server, alarm(12, 103, now + 3, name="cam2"))
    wait_for(lambda: toasts.count() == 1, 10, "the new event's toast")


def test_a_snapshot_deleted_in_another_tab_shows_as_deleted_not_as_a_broken_picture(
    serve: Callable[..., Running], page: Any
) -> None:
    server = serve()
    app: Any = server.server.config.app
    db = app.state.services.database
    started = time.time() - 60
    event = db.add_event(7, started, [[10, 20, 30, 40]], 1200.0)
    db.end_event(event, started + 2, 1200.0)
    kept = [add_snapshot(server, 7, started - 10 + i) for i in range(3)]
    gone = add_snapshot(server, 7, started + 1, "frame", event)  # The newest: the first tile.
    # This page asks for the picture only after the other tab has deleted it, as a tile
    # far down the gallery (loaded lazily) or a page opened meanwhile does.
    held: list[Any] = []
    picture = f"**/api/snapshots/{gone}.jpg"
    page.route(picture, lambda route: held.append(route))
    open_page(server, page)
    wait_for(lambda: page.locator("#thumbs figure").count() == 4, 10, "the gallery")
    wait_for(lambda: held or page.wait_for_timeout(50), 10, "the picture asked for")

    other = page.context.new_page()
    other.on("dialog", lambda dialog: dialog.accept())  # "Delete 1 snapshot(s)?"
    open_page(server, other)
    other.locator(f'#thumbs input[value="{gone}"]').check()
    other.click("#delete-selected")
    wait_for(
        lambda: httpx.get(f"{server.base}/api/snapshots/{gone}.jpg").status_code == 404,
        10,
        "the snapshot deleted by the other tab",
    )
    for route in held:
        route.continue_()  # Now a 404.
    page.unroute(picture)

    tile = page.locator("#thumbs figure").first
    wait_for(lambda: "snapshot deleted" in tile.inner_text(), 10, "the tile to say so")
    assert tile.locator("img").evaluate_all(BROKEN) == [], "a broken picture"
    # Neither selected nor zipped: "select all" ticks the others, and both zips hold them.
    page.locator("#select-all").check()
    href = page.locator("#zip-selected").get_attribute("href")
    assert sorted(int(i) for i in parse_qs(urlsplit(href).query)["ids"][0].split(",")) == kept
    assert page.locator("#select-all").is_checked()
    assert "all 3 shown" in page.locator("#zip-all").inner_text()
    run = parse_qs(urlsplit(page.locator("#zip-all").get_attribute("href")).query)
    assert "ids" not in run and gone not in (int(run["until_id"][0]), int(run["since_id"][0]))
    assert zipped_ids(page, server.base) == kept

    # The alarm that showed it says so; a toast with it shows no broken picture either.
    entry = page.locator(f'#alarm-list li[data-event="{event}"]')
    wait_for(lambda: "snapshot deleted" in entry.inner_text(), 10, "the alarm entry to say so")
    assert entry.locator("img").count() == 0
    message = alarm(7, event + 1, time.time(), name="cam7")
    message["snapshot"] = f"/api/snapshots/{gone}.jpg"
    publish(server, message)
    toast = page.locator("#toasts .toast").first
    toast.wait_for(timeout=10000)
    wait_for(
        lambda: toast.locator("img").evaluate_all(BROKEN) == [], 10, "no broken picture in a toast"
    )
    other.close()


def test_an_alarm_lists_only_the_snapshots_newer_than_the_newest_shown(
    serve: Callable[..., Running], page: Any
) -> None:
    server = serve()
    ids = [add_snapshot(server, 1, T0 + i) for i in range(230)]
    shown = ids[::-1]
    open_page(server, page)
    wait_for(lambda: page.locator("#thumbs figure").count() == 200, 10, "the first page")
    page.get_by_role("button", name="Show older").click()
    wait_for(lambda: page.locator("#thumbs figure").count() == 230, 10, "the older ones")
    listings: list[str] = []
    page.on("request", lambda r: listings.append(r.url) if "/api/snapshots?" in r.url else None)

    def after_an_alarm(count: int) -> dict[str, list[str]]:
        """An alarm comes; the gallery shows ``count``; the one listing it asked for."""
        listings.clear()
        publish(server, alarm(1, 1, time.time()))
        wait_for(lambda: page.locator("#thumbs figure").count() == count, 10, "the new ones")
        page.wait_for_timeout(300)  # Nothing more is asked for.
        assert len(listings) == 1, listings
        return parse_qs(urlsplit(listings[0]).query)

    # Two new snapshots at one time: only what is newer than the newest shown is asked for.
    first, second = add_snapshot(server, 1, T0 + 500), add_snapshot(server, 1, T0 + 500)
    query = after_an_alarm(232)
    assert float(query["since"][0]) == T0 + 229 and int(query["since_id"][0]) == ids[-1] + 1
    assert "until" not in query and int(query["limit"][0]) <= 201, query
    shown = [second, first, *shown]
    assert thumbnail_ids(page) == shown  # On top, the older ones kept, none twice.

    # One more at the newest's very time: the cursor's id keeps it, and leaves the others.
    third = add_snapshot(server, 1, T0 + 500)
    query = after_an_alarm(233)
    assert float(query["since"][0]) == T0 + 500 and int(query["since_id"][0]) == second + 1
    shown = [third, *shown]
    assert thumbnail_ids(page) == shown
    assert "all 233 shown" in page.locator("#zip-all").inner_text()

    # New filters list from the newest again, the whole first page.
    listings.clear()
    page.locator("#gallery-filter button[type=submit]").click()
    wait_for(lambda: page.locator("#thumbs figure").count() == 200, 10, "the first page again")
    query = parse_qs(urlsplit(listings[-1]).query)
    assert "since" not in query and query["limit"] == ["201"], query
    assert thumbnail_ids(page) == shown[:200]
