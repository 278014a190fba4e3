"""Gain compensation: the background lit as the frame is, each frame.

Auto-exposure and clouds scale the whole picture; the background is scaled to the
frame's brightness (the frame's gain), the ratio taken over pixels that were still and
still look like the background. Mains light read by a rolling shutter lights the rows
in bands that drift from frame to frame: where the rows' ratios spread across the
frame, each row gets its own gain. Compiled: it runs inside the per-pixel step.
"""

from __future__ import annotations

import numpy as np

from app.vision.compiled import compiled_helper
from app.vision.types import FloatImage, GrayImage, Mask

GAIN_INLIERS = 3.0
"""Pixels further than this many thresholds from the background do not set the gain."""

GAIN_GRID = 4
"""The gain is measured on every GAIN_GRID-th row and column."""

ROW_GAIN_REACH = 2
"""Sampled rows (every ``GAIN_GRID``-th) each way over which a row's gain is measured."""

ROW_GAIN_LEAST = 0.25
"""The share of a row gain's samples that must look like background for it to count."""

BANDS_LEAST = 0.06
"""The least spread, as a share of the frame's gain, between the rows' gains a fifth from
the lowest and a fifth from the highest that shows bands of light: an object that the
last mask missed can lift the gains of its own rows, not of three fifths of them."""

ROW_GAIN_SPREAD = 0.4
"""How far, as a share of its background, a band of light may take a pixel from it."""


def row_gains(height: int) -> np.ndarray:
    """Each row's gain, as ``gains`` measures it on frames ``height`` high."""
    return np.ones(height, np.float32)


@compiled_helper
def gains(
    gray: GrayImage,
    background: FloatImage,
    previous_mask: Mask,
    step: int,
    limit: float,
    frame_gain: bool,
    banded: bool,
    out: FloatImage,
) -> float:
    """Brightness ratio of frame to background over pixels that look like background,
    the frame's (returned) and each row's (``out``); 1 without ``frame_gain``, the
    frame's for every row without ``banded``.

    Pixels moving in the previous frame are left out, and so are pixels further
    than ``limit`` from the background now: an object just entering would
    otherwise drag the ratio. One pixel in ``step`` x ``step`` is plenty for a
    ratio of means, at a fraction of the cost. 1 where no pixel is left, or a
    mean is below 1.

    Mains light read by a rolling shutter lights the rows unevenly, in bands that
    drift from frame to frame, further from the frame's ratio than ``limit``. Each
    sampled row's ratio over the sampled rows within ``ROW_GAIN_REACH`` of it is
    taken first over pixels within ``ROW_GAIN_SPREAD`` of their background (as a
    share of it) besides ``limit``; where those ratios spread by ``BANDS_LEAST`` or
    more (five sampled rows at least), as their median (``_median_ratios``), then
    again over pixels within ``limit`` of their background lit by it, and each row
    takes its nearest sampled row's. Elsewhere (no bands: the rows' ratios
    differ only where an object the last mask missed weighs on them), and for rows
    with too few pixels to tell (``ROW_GAIN_LEAST``), the frame's.
    """
    if not frame_gain:
        out[:] = np.float32(1.0)
        return 1.0
    rows, cols = gray.shape
    sampled = (rows + step - 1) // step
    per_row = (cols + step - 1) // step
    sums = np.zeros((3, sampled + 1))  # Running sums of frame, background, count.
    frame_sum = 0.0
    background_sum = 0.0
    count = 0
    for row in range(sampled):
        y = row * step
        within, near = _row_sums(
            gray, background, previous_mask, y, step, 1.0, limit, ROW_GAIN_SPREAD
        )
        seen, model, used = within
        frame_sum += seen
        background_sum += model
        count += used
        _add_row(sums, row, near)
    gain = 1.0
    if count > 0 and background_sum >= count and frame_sum >= count:
        gain = frame_sum / background_sum
    if not banded:
        out[:] = np.float32(gain)
        return gain
    ratios = np.empty(sampled)
    _windowed_ratios(sums, per_row, gain, ratios)
    ordered = np.sort(ratios)
    if sampled < 5 or ordered[(sampled * 4) // 5] - ordered[sampled // 5] < BANDS_LEAST * gain:
        out[:] = np.float32(gain)
        return gain
    # Bands: each row's ratio again as the median over its window, which an object the
    # last mask missed does not move unless it covers half of it (the mean did).
    _median_ratios(gray, background, previous_mask, step, limit, gain, ratios)
    for row in range(sampled):  # Again, within ``limit`` of the background so lit.
        within, _ = _row_sums(gray, background, previous_mask, row * step, step, ratios[row], limit)
        _add_row(sums, row, within)
    _windowed_ratios(sums, per_row, gain, ratios)
    for y in range(rows):
        out[y] = np.float32(ratios[min((y + step // 2) // step, sampled - 1)])
    return gain


@compiled_helper
def _row_sums(
    gray: GrayImage,
    background: FloatImage,
    previous_mask: Mask,
    y: int,
    step: int,
    lit: float,
    limit: float,
    spread: float = 0.0,
) -> tuple[tuple[float, float, int], tuple[float, float, int]]:
    """Frame and background sums, and how many pixels, of row ``y``'s every ``step``-th
    pixel that was still and is within ``limit`` of its background lit by ``lit``; and
    the same of those within ``limit`` plus ``spread`` (a share of its background)."""
    frame_sum = 0.0
    background_sum = 0.0
    count = 0
    near_frame_sum = 0.0
    near_background_sum = 0.0
    near_count = 0
    for x in range(0, gray.shape[1], step):  # Selects, not branches: a toss-up.
        value = float(gray[y, x])
        model = float(background[y, x])
        still = previous_mask[y, x] == 0
        off = abs(value - model * lit)
        used = still & (off < limit)
        frame_sum += value if used else 0.0
        background_sum += model if used else 0.0
        count += used
        near = still & (off < limit + spread * model)
        near_frame_sum += value if near else 0.0
        near_background_sum += model if near else 0.0
        near_count += near
    return (frame_sum, background_sum, count), (near_frame_sum, near_background_sum, near_count)


@compiled_helper
def _add_row(sums: np.ndarray, row: int, row_sums: tuple[float, float, int]) -> None:
    """Running ``sums`` (frame, background, count) through ``row``, from the row's own."""
    frame_sum, background_sum, count = row_sums
    sums[0, row + 1] = sums[0, row] + frame_sum
    sums[1, row + 1] = sums[1, row] + background_sum
    sums[2, row + 1] = sums[2, row] + count


@compiled_helper
def _median_ratios(
    gray: GrayImage,
    background: FloatImage,
    previous_mask: Mask,
    step: int,
    limit: float,
    gain: float,
    out: np.ndarray,
) -> None:
    """Each sampled row's median ratio of frame to background over the sampled rows
    within ``ROW_GAIN_REACH`` of it, of pixels within ``ROW_GAIN_SPREAD`` of their
    background (as a share of it) besides ``limit``; ``gain`` where they are too few."""
    cols = gray.shape[1]
    sampled = out.size
    per_row = (cols + step - 1) // step
    found = np.empty((2 * ROW_GAIN_REACH + 1) * per_row)
    for row in range(sampled):
        top = max(row - ROW_GAIN_REACH, 0)
        bottom = min(row + ROW_GAIN_REACH + 1, sampled)
        count = 0
        for near in range(top, bottom):
            y = near * step
            for x in range(0, cols, step):
                value = float(gray[y, x])
                model = float(background[y, x])
                if (
                    previous_mask[y, x] == 0
                    and model >= 1.0
                    and abs(value - model) < limit + ROW_GAIN_SPREAD * model
                ):
                    found[count] = value / model
                    count += 1
        enough = count > 0 and count >= ROW_GAIN_LEAST * (bottom - top) * per_row
        out[row] = np.median(found[:count]) if enough else gain


@compiled_helper
def _windowed_ratios(sums: np.ndarray, per_row: int, gain: float, out: np.ndarray) -> None:
    """Each sampled row's ratio of frame to background over the sampled rows within
    ``ROW_GAIN_REACH`` of it, from running ``sums`` (frame, background, count; a row's
    ``per_row`` samples each); ``gain`` where they hold too few (``ROW_GAIN_LEAST``)."""
    sampled = out.size
    for row in range(sampled):
        top = max(row - ROW_GAIN_REACH, 0)
        bottom = min(row + ROW_GAIN_REACH + 1, sampled)
        frame_sum = sums[0, bottom] - sums[0, top]
        background_sum = sums[1, bottom] - sums[1, top]
        count = sums[2, bottom] - sums[2, top]
        usable = (count >= ROW_GAIN_LEAST * (bottom - top) * per_row) & (background_sum >= count)
        usable = usable & (frame_sum >= count)
        out[row] = frame_sum / background_sum if usable else gain
