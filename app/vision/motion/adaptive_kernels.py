"""The adaptive model's per-pixel arithmetic, compiled: each function is one pass over a frame.

Written as plain loops and compiled by Numba, so a frame's dozen per-pixel
steps (compare with both modes, threshold, teach the variability and the
modes, look for change) read each pixel once instead of once per OpenCV
call. Some forty whole-image OpenCV calls and the Python between them cost
a live camera most in fetching images and code that had gone cold while it
waited for its next frame. The neighbourhood steps (dilate, erode,
connected regions) stay with OpenCV, whose vector code is faster.

A grey level is compared with a threshold as OpenCV's ``threshold`` does
(``difference > floor(threshold)``, which for whole grey levels is
``difference > threshold``), and models (never negative) are rounded to grey
levels as its ``saturate_cast`` rounds (to nearest, halves to even, at most
255); grey levels are signed 64-bit inside the loops, so a difference never
wraps round. Frames must be 8-bit grey (the callers check). The kernels
release the GIL: cameras that share a process run them side by side. How
and when they are compiled and cached: ``app.vision.compiled``.
"""

from __future__ import annotations

import math

import numpy as np

from app.vision.compiled import compiled
from app.vision.types import FloatImage, GrayImage, Mask

MAX_GREY = np.int64(255)


@compiled
def gain_sums(
    gray: GrayImage,
    background: FloatImage,
    previous_mask: Mask,
    step: int,
    limit: float,
) -> tuple[float, float, int]:
    """Sums of frame and background grey, and their count, over every ``step``-th row
    and column, where the pixel was still last frame and is within ``limit`` of the
    background."""
    frame_sum = 0.0
    background_sum = 0.0
    count = 0
    rows, cols = gray.shape
    for y in range(0, rows, step):
        for x in range(0, cols, step):
            if previous_mask[y, x]:
                continue
            value = float(gray[y, x])
            model = float(background[y, x])
            if abs(value - model) < limit:
                frame_sum += value
                background_sum += model
                count += 1
    return frame_sum, background_sum, count


@compiled
def compare_with_modes(
    gray: GrayImage,
    background: FloatImage,
    alternate: FloatImage,
    weight: FloatImage,
    gain: float,
    established_weight: float,
    main_out: GrayImage,
    alternate_out: GrayImage,
    difference_out: GrayImage,
) -> None:
    """|frame - mode x gain| for both modes, and the difference to the nearer one (the
    alternate counts only once established: its weight reaches ``established_weight``)."""
    rows, cols = gray.shape
    for y in range(rows):
        for x in range(cols):
            value = np.int64(gray[y, x])  # Signed: uint8 minus uint8 would wrap.
            main = abs(value - min(np.int64(np.rint(background[y, x] * gain)), MAX_GREY))
            other = abs(value - min(np.int64(np.rint(alternate[y, x] * gain)), MAX_GREY))
            main_out[y, x] = main
            alternate_out[y, x] = other
            nearer = main
            if other < main and weight[y, x] >= established_weight:
                nearer = other
            difference_out[y, x] = nearer


@compiled
def threshold_and_limits(
    difference: GrayImage,
    deviation: FloatImage,
    threshold: float,
    noise_deviation: float,
    k: float,
    offset: float,
    raw_out: Mask,
    limit_out: GrayImage,
) -> int:
    """Raw motion (difference above the plain threshold), and each pixel's own threshold
    before the neighbourhood maximum: ``k`` x max(deviation, noise) + ``offset``.
    Returns how many pixels moved."""
    level = np.int64(np.floor(threshold))  # cv2.threshold on 8 bits compares with the floor.
    moving = 0
    rows, cols = difference.shape
    for y in range(rows):
        for x in range(cols):
            if difference[y, x] > level:
                raw_out[y, x] = 255
                moving += 1
            else:
                raw_out[y, x] = 0
            spread = max(deviation[y, x], noise_deviation)
            limit_out[y, x] = min(np.int64(np.floor(spread * k + offset)), MAX_GREY)
    return moving


@compiled
def learn(
    gray: GrayImage,
    previous_gray: GrayImage,
    difference: GrayImage,
    main: GrayImage,
    alternate_difference: GrayImage,
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
    threshold: float,
    weak_fraction: float,
    established_weight: float,
    seed_weight: float,
    learning_rate: float,
    mode_rate: float,
    deviation_rate: float,
    near_motion_deviation_rate: float,
    clip_deviation: bool,
    settled_in_out: np.ndarray,
    mask_out: Mask,
    changing_out: Mask,
    rounded_out: GrayImage,
) -> int:
    """The mask (hysteresis), then every model update one frame makes. Returns the
    number of moving pixels.

    Per pixel: moving = difference above half its own threshold and within reach of
    a strong pixel (``grown_strong``); still pixels and flips of ``raw`` not inside
    a ``solid`` region teach the variability (clipped at the pixel's threshold
    unless ``clip_deviation`` is off), still pixels ``near_motion`` that do not flip
    at ``near_motion_deviation_rate``; a still pixel teaches its nearer mode; an
    alternate that matches right after a background frame gains weight, and a value
    far from both modes replaces a weak alternate. Counts, per pixel, the frames it
    has been still (``settled_in_out``, at most 255), and writes, for the ghost step,
    the pixels that changed since the previous frame (``changing_out``) and the
    background rounded to grey levels (``rounded_out``).
    """
    # Branch-free (selects, & and | rather than if, and, or) so the loop vectorises.
    level = np.int64(np.floor(threshold))
    lr = np.float32(learning_rate)
    mr = np.float32(mode_rate)
    dr = np.float32(deviation_rate)
    near_rate = np.float32(near_motion_deviation_rate)
    seed = np.float32(seed_weight)
    full = np.float32(255.0)
    moving = 0
    rows, cols = gray.shape
    for y in range(rows):
        for x in range(cols):
            value = gray[y, x]
            shade = np.float32(value)
            nearer = difference[y, x]
            limit = per_pixel[y, x]
            weak = np.int64(np.floor(limit * weak_fraction))
            is_moving = (grown_strong[y, x] != 0) & (nearer > weak)
            still = ~is_moving
            # Variability: from still pixels and from flips of the plain threshold.
            flip = (raw[y, x] != previous_raw[y, x]) & (solid[y, x] == 0)
            calm = still & (near_motion[y, x] == 0)
            rate = dr if calm | flip else near_rate
            sample = np.float32(min(nearer, limit) if clip_deviation else nearer)
            spread = deviation[y, x]
            deviation[y, x] = spread + rate * (sample - spread) if still | flip else spread
            main_difference = main[y, x]
            other_difference = alternate_difference[y, x]
            old_weight = weight[y, x]
            established = old_weight >= established_weight
            nearer_alternate = established & (other_difference < main_difference)
            model = background[y, x]
            if_taught = model + lr * (shade - model)
            model = if_taught if still & ~nearer_alternate else model
            background[y, x] = model
            other = alternate[y, x]
            other = other + lr * (shade - other) if still & nearer_alternate else other
            # Recurrence: a match counts only right after a background frame.
            matched = (
                (other_difference <= threshold)
                & (other_difference < main_difference)
                & (previous_mask[y, x] == 0)
            )
            target = full if matched else np.float32(0.0)
            new_weight = old_weight + mr * (target - old_weight)
            # A value far from both modes replaces a weak alternate.
            unmatched = ~established & (min(main_difference, other_difference) > level)
            alternate[y, x] = shade if unmatched else other
            weight[y, x] = seed if unmatched else new_weight
            change = abs(np.int64(value) - np.int64(previous_gray[y, x]))
            changing_out[y, x] = 255 if change > level else 0
            rounded = min(np.int64(np.rint(model)), MAX_GREY)
            mask_out[y, x] = 255 if is_moving else 0
            settled_in_out[y, x] = min(np.int64(settled_in_out[y, x]) + 1, MAX_GREY) if still else 0
            rounded_out[y, x] = rounded
            moving += 1 if is_moving else 0
    return moving


@compiled
def mark_stirring(
    gray: GrayImage, lagged: GrayImage, changing: Mask, threshold: float, stirring_out: Mask
) -> None:
    """Pixels that changed since the previous frame (``changing``) or since ``lagged``,
    a few frames before: an object creeping a fraction of a pixel a frame stirs them."""
    level = np.int64(np.floor(threshold))
    rows, cols = gray.shape
    for y in range(rows):
        for x in range(cols):
            drift = abs(np.int64(gray[y, x]) - np.int64(lagged[y, x]))
            stirring_out[y, x] = 255 if (changing[y, x] != 0) | (drift > level) else 0


@compiled
def absorb_ghosts(
    gray: GrayImage,
    mask: Mask,
    changing: Mask,
    near_stirring: Mask,
    stopped: Mask,
    rounded: GrayImage,
    settled: np.ndarray,
    reach: int,
    settle_frames: int,
    margin: int,
    background: FloatImage,
) -> None:
    """Moving pixels that do not change and sit within ``margin`` of the range of the
    background of the still pixels within ``reach`` (``rounded``) become background at
    once.

    Near pixels that are changing, now or slowly (``near_stirring``: an object on
    the move), only neighbours that have been still for ``settle_frames`` frames
    (``settled``) count: a pixel just absorbed holds the object's own grey, and
    would pass its match on through the object's unchanging inside. An object that
    has ``stopped`` (``age_still_regions``) is left whole: eaten from its rim, its
    border would come to run through its own inside, where it looks like a ghost.
    """
    rows, cols = gray.shape
    for y in range(rows):
        seen = np.uint8(0)
        for x in range(cols):
            seen |= mask[y, x]
        if not seen:
            continue  # Most rows, in most frames.
        first, end = 0, cols  # From the row's first moving pixel to its last.
        while mask[y, first] == 0:
            first += 1
        while mask[y, end - 1] == 0:
            end -= 1
        top, bottom = max(0, y - reach), min(rows, y + reach + 1)
        for x in range(first, end):
            if mask[y, x] == 0 or changing[y, x] != 0 or stopped[y, x] != 0:
                continue
            least_age = settle_frames if near_stirring[y, x] != 0 else 0
            left, right = max(0, x - reach), min(cols, x + reach + 1)
            lowest = np.int64(256)
            highest = np.int64(-1)
            for ny in range(top, bottom):
                for nx in range(left, right):
                    if mask[ny, nx] == 0 and settled[ny, nx] >= least_age:
                        grey = np.int64(rounded[ny, nx])
                        lowest = min(lowest, grey)
                        highest = max(highest, grey)
            value = np.int64(gray[y, x])
            if lowest - margin <= value <= highest + margin:
                background[y, x] = np.float32(value)


@compiled
def age_still_regions(
    labels: np.ndarray,
    regions: int,
    stirring: Mask,
    gray: GrayImage,
    step: int,
    absorb_after: int,
    relit_after: int,
    relit_correlation: float,
    least_pattern: int,
    clear_edge: float,
    still_frames: np.ndarray,
    background: FloatImage,
    stopped_out: Mask,
) -> None:
    """Count on, by ``step``, the frames of each motion region (``labels`` 1..regions-1)
    in which none of its pixels is ``stirring`` (changed this frame, or since the
    frame ``step`` frames before, the last count: an object creeping a fraction of a
    pixel a frame is not stopped); any other pixel restarts at 0.

    A stale region becomes background after ``relit_after`` frames when it is not an
    object: the same scene in another light (its frame correlates with its background
    by ``relit_correlation`` or more: a lamp, a shadow), a ghost (across its border the
    frame steps less than the background does: the scene runs on where an object that
    left still stands in the model), or too small to tell (under ``least_pattern``
    pixels). Any other waits ``absorb_after`` frames: an object that stopped. Where
    its border is clearly an object's (the frame steps across it ``clear_edge`` times
    as much as the background does), its pixels are marked in ``stopped_out``, to be
    kept whole meanwhile (every other pixel is cleared).
    """
    rows, cols = labels.shape
    stale = np.ones(regions, np.bool_)
    stale[0] = False
    for y in range(rows):
        for x in range(cols):
            if stirring[y, x] != 0:
                stale[labels[y, x]] = False
    # Most regions on most checks are objects on the move, and need nothing more. The
    # stale ones large enough to judge get a row of sums: frame, background, their
    # squares and products, and the steps of frame and background across the border.
    pixels = np.zeros(regions, np.int64)
    if stale.any():
        for y in range(rows):
            for x in range(cols):
                if stale[labels[y, x]]:
                    pixels[labels[y, x]] += 1
    row = np.full(regions, -1, np.int64)
    judged = 0
    for label in range(1, regions):
        if pixels[label] >= least_pattern:
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
                seen = np.float64(gray[y, x])
                model = np.float64(background[y, x])
                sums[at, 0] += seen
                sums[at, 1] += model
                sums[at, 2] += seen * seen
                sums[at, 3] += model * model
                sums[at, 4] += seen * model
                for ny, nx in ((y - 1, x), (y + 1, x), (y, x - 1), (y, x + 1)):
                    if 0 <= ny < rows and 0 <= nx < cols and labels[ny, nx] != label:
                        sums[at, 5] += abs(np.float64(gray[ny, nx]) - seen)
                        sums[at, 6] += abs(np.float64(background[ny, nx]) - model)
    after = np.full(regions, relit_after, np.int64)
    kept = np.zeros(regions, np.bool_)
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
    for y in range(rows):
        for x in range(cols):
            label = labels[y, x]
            count = still_frames[y, x] + step if stale[label] else 0
            if count >= after[label]:
                background[y, x] = np.float32(gray[y, x])
                count = 0
            still_frames[y, x] = count
            stopped_out[y, x] = 255 if kept[label] else 0
