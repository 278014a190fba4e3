"""The dashboard in a real Chromium (Playwright), what a first-time user missed: editing a
camera's name and source on its card, older snapshots in the gallery (and a zip of just
what is shown), an upload left or cancelled midway, the nav links, the toasts, and an
alarm whose snapshot was deleted."""

from __future__ import annotations

import contextlib
import io
import time
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import pytest

from app.api.routes import analyses
from tests.api.test_api_browser_dashboard import alarm, publish
from tests.api.vigil_livekit import (
    Running,
    add_camera,
    add_snapshot,
    free_port,
    wait_for,
    wait_for_pictures,
)

pytestmark = pytest.mark.browser

T0 = 1_800_000_000.0


def nowhere() -> str:
    """A camera source that nothing answers at: its card shows, with no picture."""
    return f"http://127.0.0.1:{free_port()}/video.mjpg"


def open_page(server: Running, page: Any, cards: int = 0) -> None:
    page.goto(server.base + "/")
    page.wait_for_selector("#ws-state.badge-live", timeout=10000)
    if cards:
        page.wait_for_function(
            f"() => document.querySelectorAll('#grid .card').length === {cards}", timeout=10000
        )


def test_a_camera_s_name_and_source_are_edited_on_its_card_from_the_keyboard(
    serve: Callable[..., Running], page: Any, motion_video: Path
) -> None:
    server = serve()
    source = nowhere()
    cam = add_camera(server.base, source, name="door")
    open_page(server, page, cards=1)
    card = page.locator(f'.card[data-id="{cam}"]')
    edit = card.get_by_role("button", name="Edit")
    assert edit.count() == 1, "no Edit on the card"
    name, where = card.get_by_label("Name"), card.get_by_label("Source")

    # Reached and opened from the keyboard, the fields hold the camera as it is.
    edit.focus()
    page.keyboard.press("Enter")
    assert name.is_visible() and where.is_visible()
    assert name.evaluate("e => e === document.activeElement")
    assert (name.input_value(), where.input_value()) == ("door", source)
    # Escape leaves it, changing nothing.
    name.fill("porch")
    page.keyboard.press("Escape")
    assert not name.is_visible()
    assert card.locator(".cam-name").inner_text() == "door"

    # A source the server refuses: its reason, in words, on the form, which stays open.
    edit.click()
    where.fill("ftp://camera.example/live")
    where.press("Enter")
    error = card.locator(".edit-form .form-error")
    wait_for(lambda: error.inner_text(), 10, "the refusal on the form")
    assert "unsupported source scheme: ftp" in error.inner_text()
    assert where.is_visible()
    assert page.locator("#toasts .toast").count() == 0
    assert httpx.get(f"{server.base}/api/cameras/{cam}").json()["source"] == source

    # Cancel leaves it too.
    card.get_by_role("button", name="Cancel").click()
    assert not where.is_visible()

    # Enter saves: the card shows the new name and source, and the camera is live from it.
    edit.click()
    assert where.input_value() == source and error.inner_text() == ""
    name.fill("porch")
    where.fill(f"file://{motion_video}")
    where.press("Enter")
    name.wait_for(state="hidden", timeout=10000)  # Saved: the form closes.
    assert card.locator(".cam-name").inner_text() == "porch"
    assert card.locator(".cam-source").inner_text() == f"file://{motion_video}"
    stored = httpx.get(f"{server.base}/api/cameras/{cam}").json()
    assert (stored["name"], stored["source"]) == ("porch", f"file://{motion_video}")
    wait_for(lambda: card.locator(".state").inner_text() == "live", 20, "the camera live")
    wait_for_pictures(page, 1)


def thumbnail_ids(page: Any) -> list[int]:
    ids: list[int] = page.locator("#thumbs input").evaluate_all("bs => bs.map(b => +b.value)")
    return ids


def zipped_ids(page: Any, base: str) -> list[int]:
    """The snapshots in the zip that "Download all shown" gives."""
    href = page.locator("#zip-all").get_attribute("href")
    answer = httpx.get(base + href)
    assert answer.status_code == 200, answer.text
    names = zipfile.ZipFile(io.BytesIO(answer.content)).namelist()
    return sorted(int(n.split("/")[1].split("-")[0]) for n in names)


def test_show_older_pages_through_shared_times_and_the_zip_is_what_is_shown(
    serve: Callable[..., Running], page: Any
) -> None:
    server = serve()
    # 230 snapshots, oldest first; six of them share one time across the first page's
    # edge (the 198th to the 203rd newest). Each of another event: a camera's snapshots
    # of one time, kind and event share a file, and deleting the first page's would take
    # the pictures of the next page's (greyed as deleted, unless still in the cache).
    times = [T0 + i for i in range(230)]
    times[27:33] = [T0 + 30] * 6
    ids = [add_snapshot(server, 1, ts, event_id=i + 1) for i, ts in enumerate(times)]
    newest_first = ids[::-1]
    open_page(server, page)
    wait_for(lambda: page.locator("#thumbs figure").count() == 200, 10, "the first page")
    assert thumbnail_ids(page) == newest_first[:200]
    # "Download all shown" is what is shown, and says how many.
    assert zipped_ids(page, server.base) == sorted(newest_first[:200])
    assert "200" in page.locator("#zip-all").inner_text()

    older = page.get_by_role("button", name="Show older")
    assert older.count() == 1 and older.is_visible(), "no way to older snapshots"
    older.click()
    wait_for(lambda: page.locator("#thumbs figure").count() == 230, 10, "the older ones")
    assert thumbnail_ids(page) == newest_first  # None skipped, none twice, in order.
    assert older.is_hidden()  # No older ones left.
    assert zipped_ids(page, server.base) == sorted(ids)
    assert "230" in page.locator("#zip-all").inner_text()

    # A new snapshot (as an alarm brings): on top, the older ones still shown.
    later = add_snapshot(server, 1, T0 + 1000)
    publish(server, alarm(1, 1, time.time()))
    wait_for(lambda: page.locator("#thumbs figure").count() == 231, 10, "the new one")
    assert thumbnail_ids(page) == [later, *newest_first]
    # The filters given anew start again from the newest.
    page.locator("#gallery-filter button[type=submit]").click()
    wait_for(lambda: page.locator("#thumbs figure").count() == 200, 10, "the first page again")
    assert older.is_visible()
    # Every one shown deleted: the older ones are still there to show.
    page.on("dialog", lambda dialog: dialog.accept())  # "Delete 200 snapshot(s)?"
    page.locator("#select-all").check()
    page.click("#delete-selected")
    wait_for(lambda: page.locator("#thumbs figure").count() == 0, 10, "the page deleted")
    assert "older ones are below" in page.locator("#thumbs").inner_text()
    older.click()
    wait_for(lambda: page.locator("#thumbs figure").count() == 31, 10, "the rest")
    assert thumbnail_ids(page) == newest_first[199:]


def test_an_alarm_s_refresh_and_show_older_at_once_both_land(
    serve: Callable[..., Running], page: Any
) -> None:
    # The gallery's listings cancelled each other: the last asked won, and the other's
    # answer was dropped (a new snapshot never shown, or a click on Show older lost).
    server = serve()
    ids = [add_snapshot(server, 1, T0 + i) for i in range(230)]
    open_page(server, page)
    wait_for(lambda: page.locator("#thumbs figure").count() == 200, 10, "the first page")
    slow: list[Any] = []

    def refresh_slowly(route: Any) -> None:
        if "until_id" in route.request.url:  # Show older's page: at once.
            route.continue_()
        else:  # The refresh an alarm asks for: answered after the click.
            slow.append(route)

    page.route("**/api/snapshots?*", refresh_slowly)
    later = add_snapshot(server, 1, T0 + 1000)
    publish(server, alarm(1, 1, time.time()))  # Its refresh of the gallery: a second on.
    wait_for(lambda: slow or page.wait_for_timeout(50), 10, "the refresh asked for")
    page.get_by_role("button", name="Show older").click()
    page.wait_for_timeout(300)
    slow.pop().continue_()
    page.unroute("**/api/snapshots?*")
    wait_for(
        lambda: page.locator("#thumbs figure").count() == 231, 10, "both the new and the older"
    )
    assert thumbnail_ids(page) == [later, *ids[::-1]]


# Sets window.cardRedrawn once the card of camera `id` shows the reason 'redrawn', even if
# only until the next status.
REDRAWN_WATCH = """id => {
  window.cardRedrawn = false;
  new MutationObserver(() => {
    const reason = document.querySelector(`.card[data-id="${id}"] .reason`);
    if (reason && reason.textContent === 'redrawn') window.cardRedrawn = true;
  }).observe(document.body, {subtree: true, childList: true, characterData: true});
}"""


def test_a_save_on_the_edit_form_sends_only_what_was_changed_there_and_hides_a_password(
    serve: Callable[..., Running], page: Any
) -> None:
    server = serve()
    cam = add_camera(server.base, nowhere(), name="door")
    open_page(server, page, cards=1)
    card = page.locator(f'.card[data-id="{cam}"]')
    card.get_by_role("button", name="Edit").click()
    # Meanwhile another client points the camera elsewhere, and the page hears of it (/ws).
    elsewhere = nowhere()
    httpx.patch(f"{server.base}/api/cameras/{cam}", json={"source": elsewhere}).raise_for_status()
    wait_for(lambda: card.locator(".cam-source").inner_text() == elsewhere, 10, "the new source")
    # The user renames it only: the other client's source stays.
    card.get_by_label("Name").fill("porch")
    card.get_by_label("Name").press("Enter")
    wait_for(lambda: card.locator(".cam-name").inner_text() == "porch", 10, "the rename")
    stored = httpx.get(f"{server.base}/api/cameras/{cam}").json()
    assert (stored["name"], stored["source"]) == ("porch", elsewhere)

    # A password typed into the source is not shown on the card while it is saved.
    held: list[Any] = []
    page.route(
        f"**/api/cameras/{cam}",
        lambda route: held.append(route) if route.request.method == "PATCH" else route.continue_(),
    )
    card.get_by_role("button", name="Edit").click()
    card.get_by_label("Source").fill("rtsp://admin:n3wpass@127.0.0.1:9/live")
    card.get_by_label("Source").press("Enter")
    wait_for(lambda: held or page.wait_for_timeout(50), 10, "the save asked for")
    # A status message redraws the card meanwhile. The camera's own statuses (every
    # 0.25 s) may redraw it again at once, so the redraw is caught as it happens.
    page.evaluate(REDRAWN_WATCH, cam)
    publish(server, {"type": "status", "camera_id": cam, "reason": "redrawn"})
    page.wait_for_function("() => window.cardRedrawn")
    assert "n3wpass" not in card.inner_text()
    assert "n3wpass" not in (card.locator(".cam-source").get_attribute("title") or "")
    held.pop().continue_()
    card.get_by_label("Source").wait_for(state="hidden", timeout=10000)
    assert card.locator(".cam-source").inner_text() == "rtsp://admin:***@127.0.0.1:9/live"


def test_an_upload_under_way_is_warned_of_on_leaving_and_can_be_cancelled(
    serve: Callable[..., Running], page: Any, motion_video: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    server = serve()
    open_page(server, page)
    # A slow line: the video takes seconds to go out, to the real server.
    network = page.context.new_cdp_session(page)
    network.send("Network.enable")
    conditions = {"offline": False, "latency": 0, "downloadThroughput": -1}
    network.send("Network.emulateNetworkConditions", {**conditions, "uploadThroughput": 20_000})
    assert motion_video.stat().st_size > 100_000  # Five seconds or more on that line.
    page.set_input_files("#upload input[type=file]", str(motion_video))
    page.click("#upload button[type=submit]")
    panel = page.locator("#analyses .analysis").first
    bar = panel.locator("progress.upload-bar")
    wait_for(lambda: 0 < float(bar.evaluate("b => b.value")) < 1, 10, "the upload under way")
    assert panel.locator(".status").inner_text() == "uploading"

    dialogs: list[str] = []

    def answer(dialog: Any) -> None:
        dialogs.append(dialog.type)
        dialog.dismiss()  # Stay on the page.

    page.on("dialog", answer)
    page.close(run_before_unload=True)
    gone = pytest.importorskip("playwright.sync_api").Error
    with contextlib.suppress(gone):  # The page closed without asking: said below.
        wait_for(lambda: dialogs or page.wait_for_timeout(50), 5, "the browser to ask first")
    assert dialogs == ["beforeunload"], "the page closed, its upload lost, without asking"
    assert not page.is_closed()

    cancel = panel.get_by_role("button", name="Cancel upload")
    cancel.click()
    wait_for(lambda: panel.locator(".status").inner_text() == "cancelled", 5, "the cancel")
    assert panel.locator(".error").inner_text() == "Upload cancelled: the video was not sent."
    assert cancel.is_hidden()
    page.wait_for_timeout(1000)  # What reached the server was cut off: nothing to analyse.
    assert httpx.get(f"{server.base}/api/analyses").json() == []

    # At full speed, once the whole video is sent it is the server's, though the server
    # takes a while to store it and answer: no Cancel offered meanwhile.
    network.send("Network.emulateNetworkConditions", {**conditions, "uploadThroughput": -1})

    def slow_copy(*args: Any) -> int:
        time.sleep(2.0)
        return int(copy(*args))

    copy = analyses._copy_limited
    monkeypatch.setattr(analyses, "_copy_limited", slow_copy)
    page.set_input_files("#upload input[type=file]", str(motion_video))
    page.click("#upload button[type=submit]")
    sent = page.locator("#analyses .analysis").first
    wait_for(
        lambda: float(sent.locator("progress.upload-bar").evaluate("b => b.value")) == 1,
        10,
        "the video sent",
    )
    assert sent.locator(".status").inner_text() == "uploading"  # No answer yet.
    assert sent.get_by_role("button", name="Cancel upload").is_hidden()
    wait_for(lambda: sent.locator(".status").inner_text() == "done", 60, "the analysis done")
    assert len(httpx.get(f"{server.base}/api/analyses").json()) == 1
    # Nothing under way: the page closes without asking.
    with page.expect_event("close", timeout=5000):
        page.close(run_before_unload=True)
    assert dialogs == ["beforeunload"]


def test_nav_links_bring_each_section_s_heading_below_the_sticky_header(
    serve: Callable[..., Running], page: Any
) -> None:
    server = serve()
    for i in range(80):  # A long gallery: every section can scroll to the top.
        add_snapshot(server, 1, T0 + i)
    page.set_viewport_size({"width": 1400, "height": 600})
    open_page(server, page)
    wait_for(lambda: page.locator("#thumbs figure").count() == 80, 10, "the gallery")
    for link in page.locator(".top nav a").all():
        section = link.get_attribute("href")
        link.click()
        page.wait_for_function(f"() => location.hash === '{section}'")
        page.wait_for_timeout(100)
        header = page.locator(".top").bounding_box()
        heading = page.locator(f"{section} h2").bounding_box()
        assert heading["y"] >= header["y"] + header["height"], (section, heading, header)
        assert heading["y"] < 600 / 2, (section, heading)  # Brought up, not left below.


def overlaps(a: dict[str, float], b: dict[str, float]) -> bool:
    return (
        a["x"] < b["x"] + b["width"]
        and b["x"] < a["x"] + a["width"]
        and a["y"] < b["y"] + b["height"]
        and b["y"] < a["y"] + a["height"]
    )


def test_toasts_leave_the_first_row_s_pictures_and_controls_clear_and_close_by_keyboard(
    serve: Callable[..., Running], page: Any
) -> None:
    server = serve()
    cams = [add_camera(server.base, nowhere(), name=f"cam{i}") for i in range(3)]
    shot = add_snapshot(server, cams[2], time.time())
    open_page(server, page, cards=3)
    now = time.time()
    for i, cam in enumerate(cams):
        message = alarm(cam, 100 + i, now + i * 0.01, name=f"cam{i}")
        message["snapshot"] = f"/api/snapshots/{shot}.jpg"
        publish(server, message)
    toasts = page.locator("#toasts .toast")
    wait_for(lambda: toasts.count() == 3, 10, "three toasts")
    page.wait_for_timeout(300)  # Their snapshots load.

    # Not over the pictures nor the controls of the first row (the top right one was).
    covered = [t.bounding_box() for t in toasts.all()]
    parts = page.locator(
        "#grid .card .picture, #grid .card header button, #grid .card .controls > *"
    ).all()
    for part in parts:
        box = part.bounding_box()
        assert not any(overlaps(box, toast) for toast in covered), (box, covered)

    # A close button on each, reached by the keyboard; Escape closes the newest.
    close = toasts.first.get_by_role("button", name="close this message")
    assert close.count() == 1, "no close button"
    assert "cam2" in toasts.first.inner_text()
    close.focus()
    page.keyboard.press("Enter")
    wait_for(lambda: toasts.count() == 2, 5, "the toast closed")
    assert "cam1" in toasts.first.inner_text()
    page.keyboard.press("Escape")
    wait_for(lambda: toasts.count() == 1, 5, "the newest closed by Escape")
    assert "cam0" in toasts.first.inner_text()
    # An Escape that leaves a card's form is that form's only.
    card = page.locator(f'.card[data-id="{cams[0]}"]')
    card.get_by_role("button", name="Edit").click()
    card.get_by_label("Name").press("Escape")
    assert card.get_by_label("Name").is_hidden()
    page.wait_for_timeout(200)
    assert toasts.count() == 1


def test_an_alarm_whose_snapshot_was_deleted_does_not_say_it_was_not_saved(
    serve: Callable[..., Running], page: Any
) -> None:
    server = serve()
    db = server.server.config.app.state.services.database
    started = time.time() - 60
    event = db.add_event(7, started, [[10, 20, 30, 40]], 1200.0)
    db.end_event(event, started + 2, 1200.0)
    snap = add_snapshot(server, 7, started + 1, "frame", event)
    page.on("dialog", lambda dialog: dialog.accept())  # "Delete 1 snapshot(s)?"
    open_page(server, page)
    entry = page.locator(f'#alarm-list li[data-event="{event}"]')
    entry.locator("img").wait_for(timeout=10000)
    page.locator(f'#thumbs input[value="{snap}"]').check()
    page.click("#delete-selected")
    wait_for(lambda: page.locator("#thumbs figure").count() == 0, 10, "the snapshot deleted")
    wait_for(lambda: "snapshot deleted" in entry.inner_text(), 5, "the entry to say so")
    assert entry.locator("img").count() == 0
    # After a reload the page cannot tell deleted from never saved: it says neither.
    page.reload()
    entry.wait_for(timeout=10000)
    page.wait_for_timeout(500)
    assert "not saved" not in entry.inner_text()
    assert "no snapshot" in entry.inner_text()
