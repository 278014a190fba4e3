"""Ghost absorption, and its stirring guard: compiled row functions of the step.

Something in the first frame that left leaves a *ghost*: moving pixels that do not
change from frame to frame and match the background of their still neighbours. They
become background at once, eating the ghost from its rim inwards (ViBe's spatial
propagation), a ring a frame. While the scene is learned, the neighbours are sought
``LEARNING_REACH`` pixels away, past the deaf rim a start-up ghost has.

**The stirring guard**: inside an object on the move, and for a few frames after it
stops (so that the still-region check mostly sees it whole), only neighbours that
have been still for a while count, so a camouflaged object is not eaten from the one
point where it matches the background. What stirs is what changed since the previous
frame, or since a few frames back (an object creeping a fraction of a pixel a frame).
Regions the still-region check keeps whole (``regions``) are left alone.
"""

from __future__ import annotations

import numpy as np

from app.vision.compiled import compiled_helper
from app.vision.motion.adaptive.model import ON_THE_MOVE
from app.vision.motion.adaptive.rows import RING
from app.vision.types import FloatImage, GrayImage, Mask

LEARNING_REACH = 3
"""Pixels each way: how deep "inside" a region is, and how far a ghost's rim reaches,
while the scene is being learned."""

GUARD_REACH = 3
"""Pixels each way from a changing one within which the ghost step takes only settled
neighbours."""

LEARNING_SETTLE_FRAMES = 5
"""``settle_frames`` while the scene is being learned: ghosts of what was in the first
frame are expected then, and are eaten sooner."""


@compiled_helper
def stirring_row(
    gray: GrayImage,
    lagged: GrayImage,
    changing: Mask,
    level: np.float32,
    guard_frames: int,
    out: Mask,
    stirred: np.ndarray,
    y: int,
) -> None:
    """Row ``y``'s pixels that changed since the previous frame (``changing``) or since
    ``lagged``, into ``out``; and in ``stirred``, frames left of the ghost step's guard:
    ``guard_frames`` where a pixel stirs, one fewer each frame it does not."""
    start = np.uint8(guard_frames)
    for x in range(gray.shape[1]):
        drift = abs(np.float32(gray[y, x]) - np.float32(lagged[y, x]))
        stirs = (changing[x] != 0) | (drift > level)
        out[y, x] = np.uint8(255) if stirs else np.uint8(0)
        left = stirred[y, x]
        stirred[y, x] = start if stirs else left - np.uint8(left > 0)


@compiled_helper
def absorb_ghosts_row(
    gray: GrayImage,
    mask: Mask,
    changing: Mask,
    near_stirring: Mask,
    kept: Mask,
    rounded: np.ndarray,
    settled: np.ndarray,
    y: int,
    reach: int,
    settle_frames: int,
    margin: int,
    background: FloatImage,
) -> None:
    """Row ``y``'s moving pixels (the caller calls only for a row that has some) that do
    not change and sit within ``margin`` of the range of the background of the still
    pixels within ``reach`` (``rounded``, a ring of rows) become background at once.

    A real object does not match the background around it, so it stays; and since a
    ghost does not change from frame to frame, pixels that change are left alone, or
    the soft rim of a faint moving object would be eaten and leave a trail behind it.
    While the scene is being learned, ``reach`` is 3 rather than 1: the background is
    then the first frame, and the variability learned while a ghost's object left has
    made its rim deaf, hiding the true background from a 3x3 search for seconds.

    Near pixels that are changing, now or slowly, or did a few frames ago
    (``near_stirring``), only neighbours that have been still for ``settle_frames``
    frames (``settled``) count: where a camouflaged object matches the background at
    a point of its rim, that point is absorbed with the object's grey, and would
    otherwise pass the match on, ring by ring, through the object's unchanging inside.
    An object that has stopped, or moves with an unchanging inside (``kept``), is left
    whole: eaten from its rim, its border would come to run through its own inside,
    where it looks like a ghost.
    """
    rows, cols = mask.shape
    first, end = 0, cols  # From the row's first moving pixel to its last (it has one).
    while mask[y, first] == 0:
        first += 1
    while mask[y, end - 1] == 0:
        end -= 1
    top, bottom = max(0, y - reach), min(rows, y + reach + 1)
    for x in range(first, end):
        if mask[y, x] == 0 or changing[x] != 0 or kept[y, x] >= ON_THE_MOVE:
            continue
        least_age = settle_frames if near_stirring[x] != 0 else 0
        left, right = max(0, x - reach), min(cols, x + reach + 1)
        lowest = 256
        highest = -1
        for ny in range(top, bottom):
            for nx in range(left, right):
                if mask[ny, nx] == 0 and settled[ny, nx] >= least_age:
                    grey = int(rounded[ny % RING, nx])
                    lowest = min(lowest, grey)
                    highest = max(highest, grey)
        value = int(gray[y, x])
        if lowest - margin <= value <= highest + margin:
            background[y, x] = np.float32(value)
