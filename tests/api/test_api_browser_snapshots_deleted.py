"""A snapshot deleted in another tab, its picture already loaded here: the page hears of it
on /ws (``snapshots_deleted``) and stops showing it at once, with no reload, no new alarm
and no listing asked for."""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from typing import Any

import httpx
import pytest

from tests.api.test_api_browser_dashboard import alarm, publish
from tests.api.test_api_browser_editing import open_page, zipped_ids
from tests.api.vigil_livekit import Running, add_snapshot, hold_answers, wait_for

pytestmark = pytest.mark.browser

GALLERY_LISTING = re.compile(r"/api/snapshots\?")

LOADED = "imgs => imgs.filter(i => i.complete && i.naturalWidth > 0).length"
"""Of the pictures given, how many the browser has loaded and shows."""


def delete_in_another_tab(server: Running, page: Any, snapshot: int) -> None:
    """Another page of the same browser deletes ``snapshot`` from its gallery."""
    other = page.context.new_page()
    other.on("dialog", lambda dialog: dialog.accept())  # "Delete 1 snapshot(s)?"
    open_page(server, other)
    other.locator(f'#thumbs input[value="{snapshot}"]').check()
    with other.expect_response("**/api/snapshots/delete") as answer:
        other.click("#delete-selected")
    assert answer.value.json() == {"deleted": [snapshot]}


def add_alarm_with_snapshot(server: Running, ts: float) -> tuple[int, int]:
    """An ended event of camera 7 that started at ``ts``, and its snapshot: their ids."""
    db = server.server.config.app.state.services.database
    event = db.add_event(7, ts, [[10, 20, 30, 40]], 1200.0)
    db.end_event(event, ts + 2, 1200.0)
    return event, add_snapshot(server, 7, ts + 1, "frame", event)


def test_a_loaded_snapshot_deleted_in_another_tab_goes_from_gallery_alarms_and_toasts(
    serve: Callable[..., Running], page: Any
) -> None:
    server = serve()
    started = time.time() - 60
    kept = [add_snapshot(server, 7, started - 10 + i) for i in range(2)]
    event, gone = add_alarm_with_snapshot(server, started)  # The newest: the first tile.
    open_page(server, page)
    tile = page.locator(f'#thumbs figure[data-id="{gone}"]')
    entry = page.locator(f'#alarm-list li[data-event="{event}"]')
    message = alarm(7, event + 1, time.time(), name="cam7")  # A toast that shows it too.
    message["snapshot"] = f"/api/snapshots/{gone}.jpg"
    # The alarm's own refresh of the gallery (a second on), out of the way first.
    with page.expect_response(lambda answer: "since_id=" in answer.url):
        publish(server, message)
    toast = page.locator("#toasts .toast").first
    for place in (tile, entry, toast):
        wait_for(lambda p=place: p.locator("img").evaluate_all(LOADED) == 1, 10, "its picture")
    assert "all 3 shown" in page.locator("#zip-all").inner_text()
    asked: list[str] = []
    page.on("request", lambda r: asked.append(r.url) if "/api/snapshots" in r.url else None)

    delete_in_another_tab(server, page, gone)

    # The toast first: it closes itself 8 s after the alarm.
    wait_for(lambda: toast.locator("img").count() == 0, 5, "the toast to drop the picture")
    assert "Motion on cam7" in toast.inner_text(timeout=1000), "the toast itself stays"
    wait_for(lambda: tile.locator("img").count() == 0, 10, "the tile to stop showing it")
    assert "snapshot deleted" in tile.inner_text()
    assert "all 2 shown" in page.locator("#zip-all").inner_text()
    assert zipped_ids(page, server.base) == kept
    page.locator("#select-all").check()
    ticked = page.locator("#thumbs input:checked").evaluate_all("bs => bs.map(b => +b.value)")
    assert sorted(ticked) == kept, "select all ticks only those that stand"
    wait_for(lambda: "snapshot deleted" in entry.inner_text(), 5, "the alarm entry to say so")
    assert entry.locator("img").count() == 0
    # Told, not found out: no picture failed to load, and the gallery was not listed again.
    assert asked == [], asked


def test_a_listing_answered_before_the_delete_does_not_bring_the_snapshot_back(
    serve: Callable[..., Running], page: Any
) -> None:
    server = serve()
    now = time.time()
    kept = add_snapshot(server, 7, now - 10)
    gone = add_snapshot(server, 7, now)
    open_page(server, page)
    tile = page.locator(f'#thumbs figure[data-id="{gone}"]')
    wait_for(lambda: tile.locator("img").evaluate_all(LOADED) == 1, 10, "its picture")
    # The picture drawn again comes as from the browser's cache, as it may: only the
    # message tells the page it is gone.
    picture = httpx.get(f"{server.base}/api/snapshots/{gone}.jpg").content
    page.route(
        f"**/api/snapshots/{gone}.jpg",
        lambda route: route.fulfill(body=picture, content_type="image/jpeg"),
    )
    # The gallery is listed again (new filters), answered while the snapshot still stands,
    # and the answer reaches the page only after /ws has told of the delete.
    held = hold_answers(page, GALLERY_LISTING)
    newest = add_snapshot(server, 7, now + 10)  # Shown once the listing has been drawn.
    page.locator("#gallery-filter button[type=submit]").click()
    wait_for(lambda: held or page.wait_for_timeout(50), 10, "the listing to be answered")
    delete_in_another_tab(server, page, gone)
    page.wait_for_timeout(300)  # The page hears of it meanwhile.
    for route, answer in held:
        route.fulfill(response=answer)
    page.unroute(GALLERY_LISTING)
    # The listing drawn, and in the same turn what the message tells, before the next look.
    page.locator(f'#thumbs figure[data-id="{newest}"]').wait_for(timeout=10000)
    assert tile.locator("img").count() == 0 and "snapshot deleted" in tile.inner_text()
    assert "all 2 shown" in page.locator("#zip-all").inner_text()
    assert zipped_ids(page, server.base) == [kept, newest]
