"""A view that shifted in the picture (a knocked camera): moving images by it, and
whether it explains how one picture differs from another."""

from __future__ import annotations

import itertools
import math

import cv2
import numpy as np

VIEW_SHIFT_REACH = 0.08
"""The largest shift of a view taken for a camera that moved, as a share of the picture's
width: a knock moves the view a few pixels; a larger shift between two pictures is a pan
(not followed) or what an object's own move looks like on a plain scene."""

PAN_REACH = 0.5
"""The largest shift of a view sought where the camera may have turned (a pan) between two
pictures (the start of a clip and a later stretch of it), as a share of the picture's
width. Where the scene's detail is one object's, its own move is not taken for the view's
(``shift_explains``)."""

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

SHIFT_SPREAD = 0.5
"""The least share of the view's width, and of its height, that the detail a shift moves
must span for the shift to tell a moved view: detail within less may all be one
object's on a plain scene (a white box crossing a grey wall), which its own shift
explains as well as a moved view would, and an object moving is what a motion detector
reports. A view's detail is spread over it, if thinly (a few signs on plain walls)."""


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


LEAST_SHIFT_SIDE = 16
"""Pixels: a picture narrower (or lower) than this is not searched for a moved view."""


def moved_view(
    reference: np.ndarray, picture: np.ndarray, threshold: float, least_px: float, step: int = 1
) -> tuple[float, float] | None:
    """How far (x, y pixels) the whole view moved from ``reference`` to ``picture``
    (float32 grey levels): the shift phase correlation finds, where it is ``least_px`` to
    ``PAN_REACH`` of the width and explains how the picture differs by more than
    ``threshold`` (``shift_explains``, on every ``step``-th row and column). None where
    no shift does, or the pictures are too small to tell (``LEAST_SHIFT_SIDE``)."""
    height, width = reference.shape
    if min(height, width) < LEAST_SHIFT_SIDE:
        return None
    taper = cv2.createHanningWindow((width, height), cv2.CV_32F)
    # Copies: OpenCV 5.0's phaseCorrelate applies the window to its inputs in place.
    (dx, dy), _ = cv2.phaseCorrelate(reference.copy(), picture.copy(), taper)
    if not least_px <= math.hypot(dx, dy) <= PAN_REACH * width:
        return None
    return (dx, dy) if shift_explains(reference, picture, dx, dy, threshold, step) else None


def shift_explains(
    reference: np.ndarray,
    picture: np.ndarray,
    dx: float,
    dy: float,
    threshold: float,
    step: int = 1,
) -> bool:
    """Whether ``reference`` (float32 grey levels) moved (dx, dy) explains how ``picture``
    differs from it by more than ``threshold``: compared where both views see the scene,
    on every ``step``-th row and column, the pixels that differ are some, at most
    ``SHIFT_EXPLAINS`` of them still differ from the moved reference, and in most parts
    of the view with detail enough, at least ``SHIFT_SHOWS`` of those that the move
    changes differ. False where the views share no pixel."""
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
    return _shows_in_most_parts(moves, differ & moves)


def _shows_in_most_parts(moves: np.ndarray, shown: np.ndarray) -> bool:
    """Whether ``moves`` spans ``SHIFT_SPREAD`` of the view each way, and in all but
    ``SHIFT_MAY_MISS`` of the ``SHIFT_PARTS`` x ``SHIFT_PARTS`` parts of the view where
    ``moves`` holds ``SHIFT_DETAIL`` of the pixels, ``shown`` holds ``SHIFT_SHOWS`` of
    them."""
    height, width = moves.shape
    if _span(np.any(moves, axis=0)) < SHIFT_SPREAD * width:
        return False
    if _span(np.any(moves, axis=1)) < SHIFT_SPREAD * height:
        return False
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
    return detailed > 0 and missed <= SHIFT_MAY_MISS * detailed


def _span(held: np.ndarray) -> int:
    """From the first to the last True of a 1-D array, both counted (0 where none is)."""
    where = np.flatnonzero(held)
    return int(where[-1] - where[0] + 1) if where.size else 0
