"""The adaptive model's per-pixel work, compiled: most frames take one call.

Written as plain loops and compiled by Numba. A live camera's frame arrives
after a wait in which its images and code have gone cold, and fetching them
again, and every call's set-up, costs more than the arithmetic. So a frame's
work is one call that reads each pixel twice, its state in a few stacked
planes, and the neighbourhood steps (the largest or smallest value around a
pixel) run row by row inside it on a few rows kept hot, instead of a dozen
whole-image passes with Python between them:

1. ``step``: the frame against both modes (``_compare``); how many pixels
   differ. Where too many do for the frame to be taken in at once (a light
   may have switched, the camera been knocked), it stops there and the caller
   decides, then calls it again to learn only. Otherwise it goes on to:
2. everything one frame teaches, streamed row by row. Each
   pixel's own threshold (its variability, the largest in its 3x3), the mask
   (hysteresis: pixels above half their threshold near one above it), the
   model updates, which pixels stir, and the ghost step, each a few rows
   behind the step it reads, so every row it reads is final. Rows with nothing
   moving near them skip the neighbourhood steps.
3. ``age_still_regions``, every few frames: stale motion regions.

A grey level is compared with a threshold as OpenCV's ``threshold`` does
(``difference > floor(threshold)``, which for whole grey levels is
``difference > threshold``), and models (never negative) are rounded to grey
levels as its ``saturate_cast`` rounds (to nearest, halves to even, at most
255). A neighbourhood at the frame's edge is the part of it inside the frame,
as OpenCV's ``dilate`` and ``erode`` take it. The per-pixel arithmetic is in
float32 (whole grey levels are exact in it) and branch-free where it can be
(selects rather than if), so the loops vectorise eight pixels at a time; each
loop is compiled as a function of its own (``compiled_helper``), which
vectorises it best. Frames must be 8-bit grey (the callers check). The
kernels release the GIL: cameras that share a process run them side by side.
How and when they are compiled and cached: ``app.vision.compiled``.
"""

from __future__ import annotations

import math

import numpy as np

from app.vision.compiled import compiled, compiled_helper
from app.vision.types import FloatImage, GrayImage, Mask

MAX_GREY = np.float32(255.0)

LEAST_SIGNIFICANT = np.float32(1e-3)
"""A weight or deviation that decays below this is zero: it means nothing by then, and
left to decay it would reach float32's subnormal range (after about 90 s for an
alternate's weight) and stick there, where each operation costs many times a normal
one's: the real clip's model cost a fifth more per frame after ten minutes
(``bench_pipeline.py`` (e)), and twice as much with two pixels in five stuck."""

RING = 8
"""Rows kept of each streamed step (a power of two, above the deepest look-back)."""

# Planes of ``step``'s row rings (``ring_rows``).
_LIMIT, _PER_PIXEL, _STRONG, _CHANGING, _ROUNDED = range(5)
RING_PLANES = 5

LEARNING_REACH = 3
"""Pixels each way: how deep "inside" a region is, and how far a ghost's rim reaches,
while the scene is being learned."""

GUARD_REACH = 3
"""Pixels each way from a changing one within which the ghost step takes only settled
neighbours."""

LIMIT_AHEAD = 3
"""Rows by which a pixel's own threshold and the raw motion are computed ahead of the
row learned: the mask's neighbourhood reaches 2 rows (the strong pixels' 5x5), theirs 1
(the 3x3), and the solid region's ``LEARNING_REACH``."""

GHOST_BEHIND = max(GUARD_REACH, LEARNING_REACH)
"""Rows by which the ghost step trails the row learned: it reads the stirring pixels
within ``GUARD_REACH`` rows, and the mask within its reach (``LEARNING_REACH`` at
most)."""

# What the streamed steps read must be written by then and still in the rings: the solid
# region reads the raw motion LEARNING_REACH rows ahead, the hysteresis the strong
# pixels 2 rows ahead (written LIMIT_AHEAD - 1 ahead), the ghost step the rounded
# background its reach past GHOST_BEHIND rows back.
assert LIMIT_AHEAD - 1 >= 2, "the hysteresis would read strong pixels not yet found"
assert LEARNING_REACH <= LIMIT_AHEAD, "the solid region would read raw rows not yet made"
assert LIMIT_AHEAD + 2 <= RING, "the hysteresis would read strong rows the ring lost"
assert GHOST_BEHIND + LEARNING_REACH < RING, "the ghost step would read rows the ring lost"


# The model: float32 planes (``MODEL`` x height x width).
BACKGROUND, ALTERNATE, WEIGHT, DEVIATION = range(4)
MODEL = 4

# Its 8-bit planes (``STATE`` x height x width): frames each pixel has been still (to
# 255), what the ghost step leaves whole (``KEPT``: objects that stopped, ``STOPPED``,
# or move with an unchanging inside, ``ON_THE_MOVE``), pixels that stir, the raw motion,
# in two planes that take turns holding the previous frame's (``RAW``), and frames left
# of the ghost step's guard where a pixel stirred lately (``STIRRED``).
SETTLED, KEPT, STIRRING = range(3)
RAW = (3, 4)
STIRRED = 5
STATE = 6

# What ``KEPT`` holds for a pixel of a region the ghost step leaves whole, and (not yet
# left whole) of one first seen moving with an unchanging inside; else 0.
STOPPED = 255
ON_THE_MOVE = 128
SEEN_MOVING = 64

# A frame's outputs (``OUTPUTS`` x height x width, 8-bit): the difference to the nearer
# mode, and the mask.
DIFFERENCE, MASK = range(2)
OUTPUTS = 2

# Float32 settings of a frame (``rates``), by index.
(
    GAIN,
    THRESHOLD,
    LEVEL,
    NOISE_DEVIATION,
    K,
    WEAK_FRACTION,
    ESTABLISHED_WEIGHT,
    SEED_WEIGHT,
    LEARNING_RATE,
    MODE_RATE,
    DEVIATION_RATE,
    NEAR_MOTION_RATE,
) = range(12)
RATES = 12

# Whole-number settings of a frame (``settings``), by index: learn only (``step``),
# while the scene is being learned, anything moved last frame, the ghost step's reach,
# settle frames and margin, this frame's raw plane, the gain's grid step, and the frames
# the ghost step stays guarded where a pixel stirred.
(
    LEARN_ONLY,
    LEARNING,
    NEAR_MOTION_KNOWN,
    REACH,
    SETTLE_FRAMES,
    MARGIN,
    RAW_PLANE,
    GAIN_STEP,
    GUARD_FRAMES,
) = range(9)
SETTINGS = 9

# Float64 bounds of ``step`` (``bounds``): the gain's inlier limit, and the moving
# pixels past which the frame is only compared.
GAIN_LIMIT, COMPARE_ONLY_ABOVE = range(2)
BOUNDS = 2


ROW_GAIN_REACH = 2
"""Sampled rows (every ``GAIN_STEP``-th) each way over which a row's gain is measured
(``_gains``)."""

ROW_GAIN_LEAST = 0.25
"""The share of a row gain's samples that must look like background for it to count."""

BANDS_LEAST = 0.06
"""The least spread, as a share of the frame's gain, between the rows' gains a fifth from
the lowest and a fifth from the highest that shows bands of light: an object that the
last mask missed can lift the gains of its own rows, not of three fifths of them."""

ROW_GAIN_SPREAD = 0.4
"""How far, as a share of its background, a band of light may take a pixel from it."""

QUIET_INSIDE = 0.3
"""The largest share of a moving region's pixels that may stir for the ghost step to
leave it whole (``age_still_regions``): most of it unchanged, it is an object whose
inside does not change as it moves (a lorry's plain side, something creeping), which the
ghost step would take for a ghost from the rim in, where the rim happens to match the
scene around it. A region mostly astir (leaves, a walker) is left to the guard of each
stirring pixel: kept whole, swaying leaves stayed motion (CDnet fall's F, over all frames
with the scan, fell from 0.910 to 0.887 with every region on the move kept; with this
share, and two checks running, it stays 0.910)."""


def ring_rows(width: int) -> np.ndarray:
    """Scratch rows for ``step`` on frames ``width`` wide."""
    return np.empty((RING_PLANES, RING, width), np.uint8)


def row_gains(height: int) -> np.ndarray:
    """Each row's gain, as ``step`` measures it on frames ``height`` high."""
    return np.ones(height, np.float32)


@compiled
def step(
    gray: GrayImage,
    previous_gray: GrayImage,
    lagged: GrayImage,
    previous_mask: Mask,
    model: np.ndarray,
    state: np.ndarray,
    rings: np.ndarray,
    gains: FloatImage,
    outputs: np.ndarray,
    rates: np.ndarray,
    settings: np.ndarray,
    bounds: np.ndarray,
) -> tuple[int, float, int]:
    """A frame against the model, then, unless more than ``bounds[COMPARE_ONLY_ABOVE]``
    pixels differ by more than the threshold (a light may have switched, the camera
    moved: the caller decides), everything it teaches, in one call. With
    ``settings[LEARN_ONLY]``, the frame was compared by an earlier call (its
    difference is in ``outputs``, its gain in ``rates``): only what it teaches.

    Returns the pixels that differ (-1 where it learned only), the gain (``_gain``,
    set in ``rates`` too) and the pixels that move (-1 where it only compared). (One
    kernel for both calls: a kernel is compiled with all it calls, so each costs
    seconds on a machine's first run.)

    ``rates`` (float32, ``RATES``): the gain, the threshold and its whole grey
    levels, the noise's mean deviation, ``k`` and the weak fraction (of a pixel's own
    threshold), the established and seed weights, the learning, mode,
    deviation and near-motion deviation rates; ``settings`` (``SETTINGS``).
    ``gains`` (float32, a row each) gets each row's gain (``_gains``), which
    the modes are lit by. ``outputs[DIFFERENCE]`` gets the frame's difference to the
    nearer mode (``_compare``), ``outputs[MASK]`` the mask.

    What a frame teaches, row by row, each step a fixed number of rows behind the
    one it reads:

    * each pixel's own threshold, ``k`` x max(deviation, noise) + the offset that
      makes the plain one the threshold, then the largest in its 3x3 (a leaf's
      variability is its neighbour's a moment later), and the strong pixels,
      above it (``LIMIT_AHEAD`` rows ahead);
    * the mask: pixels above the weak fraction of their threshold within the 5x5
      (ellipse) of a strong pixel; then what the frame teaches (``_learn_row``);
    * which pixels stir: changed since the previous frame or since ``lagged``, a
      few frames before (an object creeping a fraction of a pixel a frame);
    * the ghost step (``_absorb_ghosts_row``, ``GHOST_BEHIND`` rows behind).

    The raw motion (the difference above the plain threshold) goes to the state's
    ``RAW_PLANE``; the other raw plane holds last frame's. While ``LEARNING``,
    flips deep inside a solid raw region (its 7x7) do not teach the variability
    and it is not clipped; otherwise, once ``NEAR_MOTION_KNOWN`` (anything moved
    last frame), still pixels within the 7x7 of the last mask teach it at the
    near-motion rate.
    """
    difference, mask_out = outputs[DIFFERENCE], outputs[MASK]
    differing = -1
    if not settings[LEARN_ONLY]:
        rates[GAIN] = _gains(
            gray, model[BACKGROUND], previous_mask, settings[GAIN_STEP], bounds[GAIN_LIMIT], gains
        )
        differing = _compare(
            gray, model, gains, rates[ESTABLISHED_WEIGHT], rates[LEVEL], difference
        )
        if differing > bounds[COMPARE_ONLY_ABOVE]:
            return differing, rates[GAIN], -1
    background, alternate = model[BACKGROUND], model[ALTERNATE]
    weight, deviation = model[WEIGHT], model[DEVIATION]
    settled, kept, stirring_out = state[SETTLED], state[KEPT], state[STIRRING]
    stirred = state[STIRRED]
    guard_frames = settings[GUARD_FRAMES]
    raw_plane = settings[RAW_PLANE]
    raw_out = state[raw_plane]
    previous_raw = state[RAW[0] + RAW[1] - raw_plane]
    learning = settings[LEARNING] != 0
    near_motion_known = settings[NEAR_MOTION_KNOWN] != 0
    reach = settings[REACH]
    settle_frames = settings[SETTLE_FRAMES]
    margin = settings[MARGIN]
    rows, cols = gray.shape
    level = rates[LEVEL]
    k = rates[K]
    noise_deviation = rates[NOISE_DEVIATION]
    offset = rates[THRESHOLD] - k * noise_deviation
    row = np.empty(cols, np.uint8)
    grown = np.empty(cols, np.uint8)
    near_motion = np.zeros(cols, np.uint8)
    solid = np.zeros(cols, np.uint8)
    near_stirring = np.empty(cols, np.uint8)
    # Which rows hold anything: most rows of most frames hold nothing that moves, and
    # their neighbourhoods need no look.
    previous_rows = np.zeros(rows, np.bool_)
    if near_motion_known:
        for y in range(rows):
            previous_rows[y] = _holds_any(previous_mask[y])
    strong_rows = np.zeros(rows, np.bool_)
    moving_rows = np.zeros(rows, np.bool_)
    guarded_rows = np.zeros(rows, np.bool_)
    moving = 0
    for ahead in range(rows + LIMIT_AHEAD + GHOST_BEHIND):
        if ahead < rows:
            _limit_row(deviation, ahead, noise_deviation, k, offset, rings[_LIMIT, ahead % RING])
            _above_row(difference, ahead, level, raw_out)
        pixel = ahead - 1  # Each pixel's threshold and the strong pixels: the 3x3 is known.
        if 0 <= pixel < rows:
            # Leaves and edges shift by a pixel or so, so a neighbour's variability is a
            # pixel's own a moment later: its threshold is the largest in its 3x3.
            _column_extreme(rings[_LIMIT], pixel, 1, rows, True, row)
            per_pixel = rings[_PER_PIXEL, pixel % RING]
            _spread_row(row, 1, True, per_pixel)
            strong = rings[_STRONG, pixel % RING]
            _above_each_row(difference[pixel], per_pixel, strong)
            strong_rows[pixel] = _holds_any(strong)
        learned = ahead - LIMIT_AHEAD
        if 0 <= learned < rows:
            # Hysteresis: pixels above half their threshold count where a strong one
            # (above it) is near, so low-contrast objects come out whole and weak
            # noise stays out.
            if _any_near(strong_rows, learned, 2):
                # The strong pixels' 5x5 ellipse: 5 wide over 3 rows, and the middle
                # column over 5.
                _column_extreme(rings[_STRONG], learned, 1, rows, True, row)
                _spread_row(row, 2, True, grown)
                _column_extreme(rings[_STRONG], learned, 2, rows, True, row)
                _merge_row(row, True, grown)
            else:
                grown[:] = 0
            if learning:
                # While the scene is learned, a flip deep inside a solid region is an
                # object stepping in or a ghost uncovered, not a sway: it does not teach.
                _column_extreme(raw_out, learned, LEARNING_REACH, rows, False, row)
                _spread_row(row, LEARNING_REACH, False, solid)
            elif _any_near(previous_rows, learned, LEARNING_REACH):
                # Still pixels next to the last frame's motion may be an object's
                # unseen parts: they teach the variability slowly.
                _column_extreme(previous_mask, learned, LEARNING_REACH, rows, True, row)
                _spread_row(row, LEARNING_REACH, True, near_motion)
            else:
                near_motion[:] = 0
            at = learned % RING
            _learn_row(
                gray,
                previous_gray,
                gains[learned],
                difference,
                rings[_PER_PIXEL, at],
                grown,
                raw_out,
                previous_raw,
                previous_mask,
                solid,
                near_motion,
                background,
                alternate,
                weight,
                deviation,
                settled,
                rates,
                not learning,
                mask_out,
                rings[_CHANGING, at],
                rings[_ROUNDED, at],
                learned,
            )
            count = _count_above(mask_out, learned, np.float32(0.0))
            moving += count
            moving_rows[learned] = count > 0
            _stirring_row(
                gray,
                lagged,
                rings[_CHANGING, at],
                level,
                guard_frames,
                stirring_out,
                stirred,
                learned,
            )
            guarded_rows[learned] = _holds_any(stirred[learned])
        ghost = learned - GHOST_BEHIND
        if 0 <= ghost < rows and moving_rows[ghost]:
            if _any_near(guarded_rows, ghost, GUARD_REACH):
                _column_extreme(stirred, ghost, GUARD_REACH, rows, True, row)
                _spread_row(row, GUARD_REACH, True, near_stirring)
            else:
                near_stirring[:] = 0
            _absorb_ghosts_row(
                gray,
                mask_out,
                rings[_CHANGING, ghost % RING],
                near_stirring,
                kept,
                rings[_ROUNDED],
                settled,
                ghost,
                reach,
                settle_frames,
                margin,
                background,
            )
    return differing, rates[GAIN], moving


@compiled_helper
def _compare(
    gray: GrayImage,
    model: np.ndarray,
    gains: FloatImage,
    established_weight: np.float32,
    level: np.float32,
    difference_out: GrayImage,
) -> int:
    """|frame - mode x its row's gain| to the nearer mode (the alternate counts only
    once established: its weight reaches ``established_weight``); returns how many
    pixels differ by more than ``level``."""
    moving = 0
    for y in range(gray.shape[0]):
        _nearer_difference_row(
            gray,
            model[BACKGROUND],
            model[ALTERNATE],
            model[WEIGHT],
            gains[y],
            established_weight,
            difference_out,
            y,
        )
        moving += _count_above(difference_out, y, level)
    return moving


@compiled_helper
def _gains(
    gray: GrayImage,
    background: FloatImage,
    previous_mask: Mask,
    step: int,
    limit: float,
    out: FloatImage,
) -> float:
    """Brightness ratio of frame to background over pixels that look like background,
    the frame's (returned) and each row's (``out``).

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


@compiled_helper
def _nearer_difference_row(
    gray: GrayImage,
    background: FloatImage,
    alternate: FloatImage,
    weight: FloatImage,
    gain: np.float32,
    established_weight: np.float32,
    out: GrayImage,
    y: int,
) -> None:
    for x in range(gray.shape[1]):
        shade = np.float32(gray[y, x])
        main = _mode_difference(shade, background[y, x], gain)
        other = _mode_difference(shade, alternate[y, x], gain)
        use_other = (other < main) & (weight[y, x] >= established_weight)
        out[y, x] = np.uint8(other if use_other else main)


@compiled_helper
def _mode_difference(shade: np.float32, mode: np.float32, gain: np.float32) -> np.float32:
    """|shade - mode x gain|, the mode rounded to a grey level."""
    return abs(shade - min(np.rint(mode * gain), MAX_GREY))


@compiled_helper
def _count_above(image: GrayImage, y: int, level: np.float32) -> int:
    """Pixels of row ``y`` above ``level``."""
    count = 0
    for x in range(image.shape[1]):
        count += image[y, x] > level
    return count


@compiled_helper
def _limit_row(
    deviation: FloatImage,
    y: int,
    noise_deviation: np.float32,
    k: np.float32,
    offset: np.float32,
    out: GrayImage,
) -> None:
    """A pixel's own threshold before the neighbourhood's largest: ``k`` x
    max(deviation, noise) + ``offset``, to a grey level (never below the plain one)."""
    for x in range(deviation.shape[1]):
        spread = max(deviation[y, x], noise_deviation)
        out[x] = np.uint8(min(np.floor(spread * k + offset), MAX_GREY))


@compiled_helper
def _above_row(values: GrayImage, y: int, level: np.float32, out: Mask) -> None:
    for x in range(values.shape[1]):
        out[y, x] = np.uint8(255) if values[y, x] > level else np.uint8(0)


@compiled_helper
def _above_each_row(values: GrayImage, limits: GrayImage, out: Mask) -> None:
    for x in range(values.size):
        out[x] = np.uint8(255) if values[x] > limits[x] else np.uint8(0)


@compiled_helper
def _learn_row(
    gray: GrayImage,
    previous_gray: GrayImage,
    gain: np.float32,
    difference: GrayImage,
    per_pixel: GrayImage,
    grown_strong: Mask,
    raw: Mask,
    previous_raw: Mask,
    previous_mask: Mask,
    solid: Mask,
    near_motion: Mask,
    background: FloatImage,
    alternate: FloatImage,
    weight: FloatImage,
    deviation: FloatImage,
    settled: np.ndarray,
    rates: np.ndarray,
    clip_deviation: bool,
    mask_out: Mask,
    changing_out: Mask,
    rounded_out: GrayImage,
    y: int,
) -> None:
    """Row ``y``'s mask (hysteresis), then every model update it makes.

    Per pixel: moving = difference above the weak fraction of its own threshold
    and within reach of a strong pixel (``grown_strong``); still pixels and flips
    of ``raw`` not inside a ``solid`` region teach the variability (clipped at the
    pixel's threshold unless ``clip_deviation`` is off), still pixels
    ``near_motion`` that do not flip at the near-motion rate; a still pixel
    teaches its nearer mode; an alternate that matches right after a background
    frame gains weight, and a value far from both modes replaces a weak
    alternate (with a fresh weight only right after a background frame). Counts,
    per pixel, the frames it has been still (``settled``, at most 255), and writes,
    for the ghost step, the pixels that changed since the previous frame
    (``changing_out``) and the background rounded to grey levels (``rounded_out``).
    ``per_pixel``, ``grown_strong``, ``solid``, ``near_motion`` and the two outs are
    rows; the rest whole images.
    """
    level = rates[LEVEL]
    weak_fraction = rates[WEAK_FRACTION]
    established_weight = rates[ESTABLISHED_WEIGHT]
    seed = rates[SEED_WEIGHT]
    lr = rates[LEARNING_RATE]
    mr = rates[MODE_RATE]
    dr = rates[DEVIATION_RATE]
    near_rate = rates[NEAR_MOTION_RATE]
    full = np.float32(255.0)
    none = np.float32(0.0)
    for x in range(gray.shape[1]):
        shade = np.float32(gray[y, x])
        nearer = np.float32(difference[y, x])
        limit = np.float32(per_pixel[x])
        is_moving = (grown_strong[x] != 0) & (nearer > limit * weak_fraction)
        still = not is_moving
        # Variability: from still pixels and from flips of the plain threshold.
        flip = (raw[y, x] != previous_raw[y, x]) & (solid[x] == 0)
        calm = still & (near_motion[x] == 0)
        rate = dr if calm | flip else near_rate
        sample = min(nearer, limit) if clip_deviation else nearer
        spread = deviation[y, x]
        spread = spread + rate * (sample - spread) if still | flip else spread
        deviation[y, x] = spread if spread >= LEAST_SIGNIFICANT else none
        model = background[y, x]
        other = alternate[y, x]
        # The mode differences, as ``_compare`` found them.
        main_difference = _mode_difference(shade, model, gain)
        other_difference = _mode_difference(shade, other, gain)
        old_weight = weight[y, x]
        established = old_weight >= established_weight
        nearer_alternate = established & (other_difference < main_difference)
        if_taught = model + lr * (shade - model)
        model = if_taught if still & (not nearer_alternate) else model
        background[y, x] = model
        other = other + lr * (shade - other) if still & nearer_alternate else other
        # Recurrence: a match counts only right after a background frame.
        matched = (
            (other_difference <= level)
            & (other_difference < main_difference)
            & (previous_mask[y, x] == 0)
        )
        target = full if matched else none
        new_weight = old_weight + mr * (target - old_weight)
        new_weight = new_weight if new_weight >= LEAST_SIGNIFICANT else none
        # A value far from both modes replaces a weak alternate. Only a sighting right
        # after a background frame seeds its weight: an object's changing inside, which
        # replaces it frame after frame, would otherwise keep it fresh while it passes.
        unmatched = (not established) & (min(main_difference, other_difference) > level)
        sighted = seed if previous_mask[y, x] == 0 else min(seed, new_weight)
        alternate[y, x] = shade if unmatched else other
        weight[y, x] = sighted if unmatched else new_weight
        change = abs(shade - np.float32(previous_gray[y, x]))
        changing_out[x] = np.uint8(255) if change > level else np.uint8(0)
        mask_out[y, x] = np.uint8(255) if is_moving else np.uint8(0)
        count = settled[y, x]
        settled[y, x] = np.uint8(count + (count < 255)) if still else np.uint8(0)
        rounded_out[x] = np.uint8(min(np.rint(model), MAX_GREY))


@compiled_helper
def _stirring_row(
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
def _absorb_ghosts_row(
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

    Where something sat in the first frame and left, the uncovered background
    matches its still neighbours: a ghost, which this eats from its rim inwards
    (ViBe's spatial propagation), a ring a frame. A real object does not match
    the background around it, so it stays; and since a ghost does not change from
    frame to frame, pixels that change are left alone, or the soft rim of a faint
    moving object would be eaten and leave a trail behind it. While the scene is
    being learned, ``reach`` is 3 rather than 1: the background is then the first
    frame, and the variability learned while a ghost's object left has made its
    rim deaf, hiding the true background from a 3x3 search for seconds.

    Near pixels that are changing, now or slowly, or did a few frames ago
    (``near_stirring``: an object on the move, or one that stopped and is not yet
    judged by the stale-region check), only neighbours that have been still for
    ``settle_frames`` frames (``settled``) count: where a camouflaged object
    matches the background at a point of its rim, that point is absorbed with the
    object's grey, and would otherwise pass the match on, ring by ring, through the
    object's unchanging inside. An object that has stopped, or moves with an
    unchanging inside (``kept``, by ``age_still_regions``), is left whole: eaten
    from its rim, its border would come to run through its own inside, where it
    looks like a ghost.
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


# Row-by-row neighbourhood steps: the largest or smallest value around each pixel,
# one row at a time, on rows kept hot.


@compiled_helper
def _holds_any(values: GrayImage) -> bool:
    """Whether any of a row's values is set."""
    largest = np.uint8(0)
    for x in range(values.size):
        largest = max(largest, values[x])
    return largest != 0


@compiled_helper
def _any_near(flags: np.ndarray, row: int, reach: int) -> bool:
    """Whether any of ``flags`` within ``reach`` of ``row`` is set."""
    for other in range(max(row - reach, 0), min(row + reach + 1, flags.size)):
        if flags[other]:
            return True
    return False


@compiled_helper
def _column_extreme(
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
        _merge_row(image[other % held], largest, out)


@compiled_helper
def _merge_row(values: GrayImage, largest: bool, out: GrayImage) -> None:
    """``out``, each value the larger (or smaller) of itself and ``values``'."""
    if largest:
        for x in range(out.size):
            out[x] = max(out[x], values[x])
    else:
        for x in range(out.size):
            out[x] = min(out[x], values[x])


@compiled_helper
def _spread_row(values: GrayImage, reach: int, largest: bool, out: GrayImage) -> None:
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


@compiled
def age_still_regions(
    labels: np.ndarray,
    top: int,
    left: int,
    regions: int,
    stirring: Mask,
    gray: GrayImage,
    step: int,
    absorb_after: int,
    relit_after: int,
    relit_correlation: float,
    least_pattern: int,
    clear_edge: float,
    keep_moving: bool,
    still_frames: np.ndarray,
    background: FloatImage,
    kept_out: Mask,
) -> None:
    """Count on, by ``step``, the frames of each motion region (``labels`` 1..regions-1)
    in which none of its pixels is ``stirring`` (changed this frame, or since the
    frame ``step`` frames before, the last count: an object creeping a fraction of a
    pixel a frame is not stopped); any other pixel restarts at 0.

    ``labels`` covers the part of the frame from (``top``, ``left``) that holds every
    region with a pixel of background around it (the frame's edge aside): the other
    images are whole frames, and outside that part nothing is a region.

    A stale region becomes background after ``relit_after`` frames when it is not an
    object: the same scene in another light (its frame correlates with its background
    by ``relit_correlation`` or more: a lamp, a shadow), a ghost (across its border the
    frame steps less than the background does: the scene runs on where an object that
    left still stands in the model), or too small to tell (under ``least_pattern``
    pixels). Any other waits ``absorb_after`` frames: an object that stopped. Where
    its border is clearly an object's (the frame steps across it ``clear_edge`` times
    as much as the background does), its pixels are marked ``STOPPED`` in
    ``kept_out``, to be kept whole meanwhile, and so is a stale region that held
    such pixels, unless it is too small to tell. With ``keep_moving``, a region on
    the move with no more than ``QUIET_INSIDE`` of its pixels stirring is marked
    ``ON_THE_MOVE``, kept whole until the next count, where it was so at the last
    count too (it held pixels so marked, or ``SEEN_MOVING``), else ``SEEN_MOVING``: a
    ghost just uncovered stirs at its rim for a count, then not at all. Every other
    pixel is cleared.
    """
    rows, cols = labels.shape
    stale = np.ones(regions, np.bool_)
    stale[0] = False
    # A region kept whole at the last check stays kept while it is stale: the ghost step
    # may have eaten some of its rim before then, and the steps across that rim, the
    # scene's grey outside in the background against the object's, would otherwise
    # make it look like a ghost, then eat it all.
    was_kept = np.zeros(regions, np.bool_)
    was_moving = np.zeros(regions, np.bool_)
    stirs = np.zeros(regions, np.int64)  # Pixels that stir, and all, of each region.
    pixels = np.zeros(regions, np.int64)
    for y in range(rows):
        for x in range(cols):
            pixels[labels[y, x]] += 1
            if stirring[top + y, left + x] != 0:
                stale[labels[y, x]] = False
                stirs[labels[y, x]] += 1
            marked = kept_out[top + y, left + x]
            if marked == STOPPED:
                was_kept[labels[y, x]] = True
            elif marked != 0:
                was_moving[labels[y, x]] = True
    # Most regions on most checks are objects on the move, and need nothing more. The
    # stale ones large enough to judge, and not kept already, get a row of sums: frame,
    # background, their squares and products, and the steps of frame and background
    # across the border.
    large = pixels >= least_pattern
    kept_again = large & stale & was_kept
    row = np.full(regions, -1, np.int64)
    judged = 0
    for label in range(1, regions):
        if large[label] and stale[label] and not kept_again[label]:
            row[label] = judged
            judged += 1
    sums = np.zeros((judged, 7), np.float64)
    if judged:
        for y in range(rows):
            for x in range(cols):
                at = row[labels[y, x]]
                if at < 0:
                    continue
                label = labels[y, x]
                seen = np.float64(gray[top + y, left + x])
                model = np.float64(background[top + y, left + x])
                sums[at, 0] += seen
                sums[at, 1] += model
                sums[at, 2] += seen * seen
                sums[at, 3] += model * model
                sums[at, 4] += seen * model
                for ny, nx in ((y - 1, x), (y + 1, x), (y, x - 1), (y, x + 1)):
                    if 0 <= ny < rows and 0 <= nx < cols and labels[ny, nx] != label:
                        sums[at, 5] += abs(np.float64(gray[top + ny, left + nx]) - seen)
                        sums[at, 6] += abs(np.float64(background[top + ny, left + nx]) - model)
    after = np.full(regions, relit_after, np.int64)
    kept = kept_again.copy()
    after[kept_again] = absorb_after
    for label in range(1, regions):
        at = row[label]
        if at < 0:
            continue
        size = np.float64(pixels[label])
        seen, model, seen_square, model_square, product, frame_step, model_step = sums[at]
        if frame_step < model_step:
            continue
        seen_spread = size * seen_square - seen * seen
        model_spread = size * model_square - model * model
        if seen_spread > 0.0 and model_spread > 0.0:
            together = (size * product - seen * model) / math.sqrt(seen_spread * model_spread)
            if together >= relit_correlation:
                continue
        after[label] = absorb_after
        kept[label] = frame_step >= clear_edge * model_step
    # What each region's pixels are marked with: kept whole as stopped, or on the move with
    # a quiet inside (kept whole where it was so at the last count too), or nothing.
    marks = np.zeros(regions, np.uint8)
    for label in range(1, regions):
        if kept[label]:
            marks[label] = STOPPED
        elif keep_moving and not stale[label] and stirs[label] <= QUIET_INSIDE * pixels[label]:
            marks[label] = ON_THE_MOVE if was_moving[label] else SEEN_MOVING
    # Outside the part, nothing is a region: every count restarts.
    still_frames[:top] = 0
    still_frames[top + rows :] = 0
    still_frames[top : top + rows, :left] = 0
    still_frames[top : top + rows, left + cols :] = 0
    kept_out[...] = 0
    for y in range(rows):
        for x in range(cols):
            label = labels[y, x]
            pixel = (top + y, left + x)
            count = still_frames[pixel] + step if stale[label] else 0
            if count >= after[label]:
                background[pixel] = np.float32(gray[pixel])
                count = 0
            still_frames[pixel] = count
            kept_out[pixel] = marks[label]
