"""Row-by-row neighbourhood steps for the compiled per-pixel step (``step``): the
largest or smallest value around each pixel, one row at a time, on rows kept hot.

A neighbourhood at the frame's edge is the part of it inside the frame, as OpenCV's
``dilate`` and ``erode`` take it. Each loop is compiled as a function of its own
(``compiled_helper``), which vectorises it best.
"""

from __future__ import annotations

import numpy as np

from app.vision.compiled import compiled_helper
from app.vision.types import GrayImage, Mask

RING = 8
"""Rows kept of each streamed step (a power of two, above the deepest look-back): a
ring's row y is row y % RING."""


@compiled_helper
def holds_any(values: GrayImage) -> bool:
    """Whether any of a row's values is set."""
    largest = np.uint8(0)
    for x in range(values.size):
        largest = max(largest, values[x])
    return largest != 0


@compiled_helper
def any_near(flags: np.ndarray, row: int, reach: int) -> bool:
    """Whether any of ``flags`` within ``reach`` of ``row`` is set."""
    for other in range(max(row - reach, 0), min(row + reach + 1, flags.size)):
        if flags[other]:
            return True
    return False


@compiled_helper
def column_extreme(
    image: np.ndarray, row: int, reach: int, rows: int, largest: bool, out: GrayImage
) -> None:
    """Per column, the largest (or smallest) of the rows within ``reach`` of ``row``
    inside the frame (``rows`` high). ``image`` holds them all, or is a ring of the
    last few (row y in row y % its height)."""
    held = image.shape[0]
    source = row % held
    for x in range(out.size):
        out[x] = image[source, x]
    for other in range(max(row - reach, 0), min(row + reach + 1, rows)):
        merge_row(image[other % held], largest, out)


@compiled_helper
def merge_row(values: GrayImage, largest: bool, out: GrayImage) -> None:
    """``out``, each value the larger (or smaller) of itself and ``values``'."""
    if largest:
        for x in range(out.size):
            out[x] = max(out[x], values[x])
    else:
        for x in range(out.size):
            out[x] = min(out[x], values[x])


@compiled_helper
def spread_row(values: GrayImage, reach: int, largest: bool, out: GrayImage) -> None:
    """Per column, the largest (or smallest) of ``values`` within ``reach`` columns
    (inside the row), into ``out``."""
    cols = values.size
    for x in range(cols):
        out[x] = values[x]
    for shift in range(1, min(reach, cols - 1) + 1):
        width = cols - shift
        if largest:
            for x in range(width):
                out[x] = max(out[x], values[x + shift])  # The value ``shift`` right ...
            for x in range(width):
                out[x + shift] = max(out[x + shift], values[x])  # ... and left.
        else:
            for x in range(width):
                out[x] = min(out[x], values[x + shift])
            for x in range(width):
                out[x + shift] = min(out[x + shift], values[x])


@compiled_helper
def count_above(image: GrayImage, y: int, level: np.float32) -> int:
    """Pixels of row ``y`` above ``level``."""
    count = 0
    for x in range(image.shape[1]):
        count += image[y, x] > level
    return count


@compiled_helper
def above_row(values: GrayImage, y: int, level: np.float32, out: Mask) -> None:
    """Row ``y`` of ``out``: 255 where ``values`` is above ``level``, else 0."""
    for x in range(values.shape[1]):
        out[y, x] = np.uint8(255) if values[y, x] > level else np.uint8(0)
