"""The page's live pictures in Chromium: sixteen cameras on a wall at 1280x800, each drawn
at its camera's rate from /ws/live, with the boxes over the moving object where the
scene's truth puts it."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.api.vigil_livekit import Running, add_camera, square_box, wait_for, wait_for_pictures

pytestmark = pytest.mark.browser

CAMERAS = 16
LOOP = 45  # Frames in the test video's loop (write_video): the square crosses in 6..36.

DRAWN = (
    "ids => ids.map(id =>"
    ' Number(document.querySelector(`.card[data-id="${id}"] canvas.live`).dataset.drawn))'
)

# For each camera, what its canvas shows now: the frame drawn and, per box of that frame,
# the median green level inside the box's middle (the picture is grey: the square is
# bright, the background about half as bright) and whether the box's left edge is red.
SHOWN = """ids => ids.map(id => {
  const canvas = document.querySelector(`.card[data-id="${id}"] canvas.live`);
  const header = canvas.liveHeader;
  if (!header) return null;
  const context = canvas.getContext('2d');
  const [width, height] = header.size;
  const scale = Math.min(canvas.width / width, canvas.height / height);
  const left = (canvas.width - width * scale) / 2, top = (canvas.height - height * scale) / 2;
  const boxes = header.detections.map(({ box: [x, y, w, h] }) => {
    const inner = context.getImageData(
      Math.round(left + (x + 0.3 * w) * scale), Math.round(top + (y + 0.3 * h) * scale),
      Math.max(1, Math.round(0.4 * w * scale)), Math.max(1, Math.round(0.4 * h * scale))).data;
    const greens = [];
    for (let i = 1; i < inner.length; i += 4) greens.push(inner[i]);
    greens.sort((a, b) => a - b);
    const edge = context.getImageData(
      Math.floor(left + x * scale) - 1, Math.round(top + (y + h / 2) * scale), 3, 1).data;
    let red = false;
    for (let i = 0; i < edge.length; i += 4) red ||= edge[i] > 200 && edge[i + 1] < 80;
    return { box: [x, y, w, h], inner: greens[greens.length >> 1], red };
  });
  return { frame: header.frame, boxes };
})"""


def iou(a: list[int], b: tuple[int, int, int, int]) -> float:
    ix = max(0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    iy = max(0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    inter = ix * iy
    return inter / (a[2] * a[3] + b[2] * b[3] - inter)


@pytest.mark.own_process  # Its rate needs the machine as a user's: see the Makefile.
def test_sixteen_cameras_on_a_wall_each_at_its_rate_with_boxes_on_the_moving_object(
    serve: Callable[..., Running], page: Any, motion_video: Path
) -> None:
    server = serve(camera_processes=2)
    page.set_viewport_size({"width": 1280, "height": 800})
    ids = [
        add_camera(server.base, f"file://{motion_video}", name=f"cam{i}", activate=True)
        for i in range(CAMERAS)
    ]
    page.goto(server.base + "/#wall")
    wait_for_pictures(page, CAMERAS, timeout_ms=60000)
    boxes = page.locator(".card .picture").evaluate_all(
        "places => places.map(p => p.getBoundingClientRect())"
        ".map(r => r.top >= 0 && r.left >= 0 && r.bottom <= innerHeight && r.right <= innerWidth)"
    )
    assert boxes == [True] * CAMERAS, "a picture is not wholly on screen"

    # Rates: every camera drawn at its camera's rate (the clip's 15 fps), all at once, once
    # the cameras keep their rate (activating sixteen takes the camera processes a while).
    wait_for(
        lambda: all(c["fps"] >= 14 for c in httpx.get(f"{server.base}/api/cameras").json()),
        30,
        "every camera at its rate",
    )
    before = page.evaluate(DRAWN, ids)
    started = time.monotonic()
    page.wait_for_timeout(8000)  # Long enough that a busy second or two averages out.
    rates = [
        (after - first) / (time.monotonic() - started)
        for first, after in zip(before, page.evaluate(DRAWN, ids), strict=True)
    ]
    # At least 10 a second each, as issue 30 asks. On a 2-core machine running the sixteen
    # cameras, their server and Chromium, the least reads 12.2 to 13.9 (eight runs) since
    # the server stopped deflating every frame, 8.6 to 14 before.
    assert min(rates) >= 10, f"frames drawn a second per camera: {rates}"

    samples = []
    for _ in range(12):
        samples.append(page.evaluate(SHOWN, ids))
        page.wait_for_timeout(250)
    # Boxes: drawn (red) over the bright square, where the scene's truth puts it.
    boxed = on_truth = 0
    for sample in samples:
        for shown in sample:
            if shown is None:
                continue
            truth = square_box((shown["frame"] - 1) % LOOP)
            for box in shown["boxes"]:
                assert truth is not None, f"a box in frame {shown['frame']}, which has no object"
                assert box["red"], "a box not drawn"
                boxed += 1
                on_truth += iou(box["box"], truth) > 0.5 and box["inner"] > 180
    assert boxed >= 2 * CAMERAS, f"only {boxed} boxes seen"
    assert on_truth >= 0.8 * boxed, f"{on_truth} of {boxed} boxes on the square"
    print(f"drawn per second: median {statistics.median(rates):.1f}, least {min(rates):.1f}")


# The colour at the middle of the square (where the scene's truth puts it in the frame
# drawn: truths[index] is [x, y, w, h] or null), and where the zone layer and the picture
# lie in the canvas, in CSS pixels.
MASKED = """([id, truths]) => {
  const canvas = document.querySelector(`.card[data-id="${id}"] canvas.live`);
  const header = canvas.liveHeader;
  if (!header || !header.mask) return null;
  const truth = truths[(header.frame - 1) % truths.length];
  if (!truth) return null;
  const [width, height] = header.size;
  const scale = Math.min(canvas.width / width, canvas.height / height);
  const left = (canvas.width - width * scale) / 2, top = (canvas.height - height * scale) / 2;
  const [x, y, w, h] = truth;
  const pixel = Array.from(canvas.getContext('2d').getImageData(
    Math.round(left + (x + w / 2) * scale), Math.round(top + (y + h / 2) * scale), 1, 1).data);
  const layer = canvas.closest('.picture').querySelector('svg.zone-layer').getBoundingClientRect();
  const shown = canvas.getBoundingClientRect();
  return {
    pixel,
    layer: [layer.left - shown.left, layer.top - shown.top, layer.width, layer.height],
    picture: [left, top, width * scale, height * scale].map(v => v / devicePixelRatio),
  };
}"""


# Each canvas's size in pixels as each frame is drawn, read as it is drawn (a mutation
# observer runs before the page lays out again): a frame drawn on a canvas of no size
# shows only after a later layout redraws it.
SIZES_WATCH = """() => {
  window.drawnSizes = [];
  new MutationObserver(records => {
    for (const { target } of records) window.drawnSizes.push([target.width, target.height]);
  }).observe(document.body, { subtree: true, attributeFilter: ['data-drawn'] });
}"""


def test_the_mask_is_tinted_and_the_zones_laid_exactly_over_the_picture(
    serve: Callable[..., Running], page: Any, motion_video: Path
) -> None:
    server = serve()
    cam = add_camera(server.base, f"file://{motion_video}", activate=True)
    zone = [[0, 0], [0.1, 0], [0.1, 0.1]]
    settings = {"show_mask": True, "mask": [zone]}
    httpx.patch(f"{server.base}/api/cameras/{cam}", json=settings).raise_for_status()
    page.goto(server.base + "/")
    page.evaluate(SIZES_WATCH)
    truths = [square_box(index) for index in range(LOOP)]
    reddish = seen = 0
    for _ in range(60):
        page.wait_for_timeout(100)
        shown = page.evaluate(MASKED, [cam, truths])
        if shown is None:
            continue
        seen += 1
        # Where the square is, the mask is set: half red over the bright grey square.
        r, g, b, _ = shown["pixel"]
        reddish += r > 200 and g < 160 and b < 160
        assert shown["layer"] == pytest.approx(shown["picture"], abs=1.5), "zones misplaced"
    assert seen >= 5 and reddish >= 0.6 * seen, f"{reddish} of {seen} tinted red"
    sizes = page.evaluate("window.drawnSizes")
    assert sizes and all(w > 0 and h > 0 for w, h in sizes), (
        f"{sum(0 in s for s in sizes)} of {len(sizes)} frames drawn at no size"
    )


# Headless Chromium keeps every tab visible (minimising its window or bringing another
# tab to the front changes nothing), so the tab is hidden as the browser would say so.
SET_HIDDEN = """hidden => {
  Object.defineProperty(document, 'hidden', { configurable: true, get: () => hidden });
  Object.defineProperty(document, 'visibilityState', {
    configurable: true, get: () => (hidden ? 'hidden' : 'visible') });
  document.dispatchEvent(new Event('visibilitychange'));
}"""


def test_a_hidden_tab_receives_no_frames_and_a_shown_one_gets_them_again(
    serve: Callable[..., Running], page: Any, motion_video: Path
) -> None:
    server = serve()
    add_camera(server.base, f"file://{motion_video}", activate=True)
    received: list[float] = []

    def on_socket(socket: Any) -> None:
        if socket.url.endswith("/ws/live"):
            socket.on("framereceived", lambda _payload: received.append(time.monotonic()))

    page.on("websocket", on_socket)
    page.goto(server.base + "/")
    wait_for_pictures(page, 1, timeout_ms=30000)

    page.evaluate(SET_HIDDEN, True)
    page.wait_for_timeout(1000)  # Frames already on their way may still land.
    hidden_at = time.monotonic()
    page.wait_for_timeout(3000)
    assert [t for t in received if t > hidden_at] == [], "frames came to a hidden tab"

    page.evaluate(SET_HIDDEN, False)
    shown_at = time.monotonic()
    page.wait_for_timeout(3000)
    rate = len([t for t in received if t > shown_at]) / 3
    assert rate >= 10, f"{rate:.1f} frames a second once the tab is shown again"
