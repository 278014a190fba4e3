"""A view that shifted in the picture (a knocked camera): moving images by it, and
whether it explains how one picture differs from another."""

from __future__ import annotations

import itertools
import math

import cv2
import numpy as np

VIEW_SHIFT_REACH = 0.08
"""The largest shift of a view from one frame to the next taken for a knocked camera, as a
share of the picture's width: a knock moves the view a few pixels; a larger sudden shift
is what an object's own move looks like on a plain scene."""

PAN_REACH = 0.25
"""The largest shift of a view sought where the camera may have turned (a pan) between two
pictures (the start of a clip and a later stretch of it), as a share of the picture's
width: phase correlation finds shifts up to about 0.3 of it, and the pictures compared
share less of the view the further it moved."""

LEAST_SHIFT_SIDE = 16
"""Pixels: a picture narrower (or lower) than this is not searched for a moved view."""

SHIFT_EXPLAINS = 0.25
"""A shift explains a change when, with the reference moved by it, at most this share of
the pixels that differed still differ (the objects in view)..."""

SHIFT_SHOWS = 0.5
"""... and, in most parts of the view (``SHIFT_PARTS``, ``SHIFT_MAY_MISS``), at least this
share of the pixels that the shift changes in the reference differ in the picture: a
view that moved moves all of its detail, where leaves that sway, which a shift of theirs
may explain, leave the still scene's detail in place."""

SHIFT_PARTS = 4
"""Parts of the view across and down in which a shift must show."""

SHIFT_DETAIL = 0.03
"""The share of a part's pixels that the shift must change for the part to count (a
part of plain wall or sky shows no move)."""

SHIFT_MAY_MISS = 0.25
"""The share of the parts with detail in which the shift need not show: what stays put
in the picture while the view moves (a camera's time stamp over plain sky, the edge of
its housing) may be all the detail of a part or two."""

SHIFT_LEAST_DETAILED = 0.5
"""The least share of the parts that must have detail for a shift to tell a knocked
camera: with less, the detail may all be one object's on a plain scene (a white box
crossing a grey wall), which its own shift explains as well as a moved view would, and an
object moving is what a motion detector reports..."""

SHIFT_SPREAD = 0.5
"""... or, for a pan (``moved_view``), the least share of the view's width, and of its
height, over which the pixels that the shift changes and that differ must spread: a
view that a camera turned to may hold a few signs on plain walls, a few parts' detail;
one object's detail, or a time stamp's that stays put, spans less."""


def shifted(
    image: np.ndarray, dx: float, dy: float, into: np.ndarray, smooth: bool = True
) -> np.ndarray:
    """``image`` moved (dx, dy) pixels, drawn over ``into``, which shows where nothing of
    ``image`` lands: bilinear (``smooth``, for grey levels), or nearest (masks, counts)."""
    move = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]])
    flags = cv2.INTER_LINEAR if smooth else cv2.INTER_NEAREST
    size = (image.shape[1], image.shape[0])
    return cv2.warpAffine(
        image, move, size, dst=into, flags=flags, borderMode=cv2.BORDER_TRANSPARENT
    )


def moved_view(
    reference: np.ndarray, picture: np.ndarray, threshold: float, least_px: float
) -> tuple[float, float] | None:
    """How far (x, y pixels) the whole view moved from ``reference`` to ``picture``
    (float32 grey levels), the camera turned or knocked between them: the shift phase
    correlation finds, where it is ``least_px`` to ``PAN_REACH`` of the width and
    explains how the picture differs by more than ``threshold`` (``shift_explains``, as
    a pan). None where no shift does, or the pictures are too small to tell
    (``LEAST_SHIFT_SIDE``)."""
    height, width = reference.shape
    if min(height, width) < LEAST_SHIFT_SIDE:
        return None
    taper = cv2.createHanningWindow((width, height), cv2.CV_32F)
    # Copies: OpenCV 5.0's phaseCorrelate applies the window to its inputs in place.
    (dx, dy), _ = cv2.phaseCorrelate(reference.copy(), picture.copy(), taper)
    if not least_px <= math.hypot(dx, dy) <= PAN_REACH * width:
        return None
    explained = shift_explains(reference, picture, dx, dy, threshold, pan=True)
    return (dx, dy) if explained else None


def shift_explains(
    reference: np.ndarray,
    picture: np.ndarray,
    dx: float,
    dy: float,
    threshold: float,
    step: int = 1,
    pan: bool = False,
) -> bool:
    """Whether ``reference`` (float32 grey levels) moved (dx, dy) explains how ``picture``
    differs from it by more than ``threshold``: compared where both views see the scene,
    on every ``step``-th row and column, the pixels that differ are some, at most
    ``SHIFT_EXPLAINS`` of them still differ from the moved reference, and in most parts
    of the view with detail enough, at least ``SHIFT_SHOWS`` of those that the move
    changes differ; those parts are ``SHIFT_LEAST_DETAILED`` of all, or, for a ``pan``,
    what the move changes and shows spreads over ``SHIFT_SPREAD`` of the view each way.
    False where the views share no pixel."""
    height, width = reference.shape
    margin_x, margin_y = math.ceil(abs(dx)) + 1, math.ceil(abs(dy)) + 1
    inside = (
        slice(margin_y, height - margin_y, step),
        slice(margin_x, width - margin_x, step),
    )
    moved = shifted(reference, dx, dy, np.zeros_like(reference))[inside]
    seen, still = picture[inside], reference[inside]
    differ = np.abs(seen - still) > threshold
    before = np.count_nonzero(differ)
    after = np.count_nonzero(np.abs(seen - moved) > threshold)
    if not before or after > SHIFT_EXPLAINS * before:
        return False
    moves = np.abs(moved - still) > threshold
    shown = differ & moves
    if pan:
        height, width = shown.shape
        if _span(np.any(shown, axis=0)) < SHIFT_SPREAD * width:
            return False
        if _span(np.any(shown, axis=1)) < SHIFT_SPREAD * height:
            return False
    return _shows_in_most_parts(moves, shown, 0.0 if pan else SHIFT_LEAST_DETAILED)


def _shows_in_most_parts(moves: np.ndarray, shown: np.ndarray, least_detailed: float) -> bool:
    """Whether in all but ``SHIFT_MAY_MISS`` of the ``SHIFT_PARTS`` x ``SHIFT_PARTS``
    parts of the view where ``moves`` holds ``SHIFT_DETAIL`` of the pixels, ``shown``
    holds ``SHIFT_SHOWS`` of them, and those parts are ``least_detailed`` of all (one at
    least)."""
    height, width = moves.shape
    rows = np.linspace(0, height, SHIFT_PARTS + 1).astype(int)
    cols = np.linspace(0, width, SHIFT_PARTS + 1).astype(int)
    detailed = missed = 0
    for top, bottom in itertools.pairwise(rows):
        for left, right in itertools.pairwise(cols):
            part = (slice(top, bottom), slice(left, right))
            changed = np.count_nonzero(moves[part])
            if changed >= max(1.0, SHIFT_DETAIL * moves[part].size):
                detailed += 1
                missed += int(np.count_nonzero(shown[part]) < SHIFT_SHOWS * changed)
    if detailed == 0 or detailed < least_detailed * SHIFT_PARTS * SHIFT_PARTS:
        return False
    return missed <= SHIFT_MAY_MISS * detailed


def _span(held: np.ndarray) -> int:
    """From the first to the last True of a 1-D array, both counted (0 where none is)."""
    where = np.flatnonzero(held)
    return int(where[-1] - where[0] + 1) if where.size else 0
