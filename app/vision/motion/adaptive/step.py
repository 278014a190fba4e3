"""The per-pixel step, compiled: a frame against the model and all it teaches, in one
call.

Written as plain loops and compiled by Numba. A live camera's frame arrives after a
wait in which its images and code have gone cold, and fetching them again, and every
call's set-up, costs more than the arithmetic. So a frame's work is one call that
reads each pixel twice, and the neighbourhood steps (``rows``) run row by row inside
it on a few rows kept hot, instead of a dozen whole-image passes with Python between
them:

1. the frame against both modes, lit by the frame's gains (``gains``,
   ``learning.compare``); how many pixels differ. Where too many do for the frame
   to be taken in at once (a light may have switched, the camera been knocked), it
   stops there and the caller decides, then calls it again to learn only.
   Otherwise it goes on to:
2. everything one frame teaches, streamed row by row, each step a fixed number of
   rows behind the one it reads, so every row it reads is final: each pixel's own
   threshold (``threshold``), the mask (hysteresis), the model updates
   (``learning``), which pixels stir, and the ghost step (``ghosts``). Rows with
   nothing moving near them skip the neighbourhood steps.

The kernel releases the GIL: cameras that share a process run it side by side. How
and when it is compiled and cached: ``app.vision.compiled``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from app.vision.compiled import compiled
from app.vision.motion.adaptive.gains import GAIN_GRID, gains
from app.vision.motion.adaptive.ghosts import (
    GUARD_REACH,
    LEARNING_REACH,
    absorb_ghosts_row,
    stirring_row,
)
from app.vision.motion.adaptive.learning import compare, learn_row
from app.vision.motion.adaptive.model import (
    FrameSettings,
    Images,
    Rates,
    as_model,
    as_rings,
    as_state,
)
from app.vision.motion.adaptive.rows import (
    RING,
    above_row,
    any_near,
    column_extreme,
    count_above,
    holds_any,
    merge_row,
    spread_row,
)
from app.vision.motion.adaptive.threshold import above_each_row, limit_row
from app.vision.types import FloatImage, GrayImage, Mask

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


@compiled
def step(
    gray: GrayImage,
    previous_gray: GrayImage,
    lagged: GrayImage,
    previous_mask: Mask,
    difference: GrayImage,
    mask_out: Mask,
    raw: Mask,
    raw_out: Mask,
    model_planes: np.ndarray,
    state_planes: np.ndarray,
    ring_planes: np.ndarray,
    row_gains: FloatImage,
    rate_values: tuple[Any, ...],
    frame_values: tuple[Any, ...],
    learn_only: bool,
) -> tuple[int, int]:
    """A frame against the model, then, unless more than ``frame.compare_only_above``
    pixels differ by more than the threshold (the caller decides), everything it
    teaches. With ``learn_only``, the frame was compared by an earlier call (its
    difference is in ``difference``, its gains in ``row_gains``): only what it teaches.

    Returns the pixels that differ (-1 where it learned only) and the pixels that move
    (-1 where it only compared). (One kernel for both calls: a kernel is compiled with
    all it calls, so each costs seconds on a machine's first run.)

    The model, the state and the rings come as their planes (``model``), the
    ``Rates`` and the ``FrameSettings`` as plain tuples of their values. ``row_gains``
    (a row each) gets each row's gain, which the modes are lit by; ``difference`` the
    frame's difference to the nearer mode, ``mask_out`` the mask.
    What a frame teaches, row by row:

    * each pixel's own threshold, ``k`` x max(deviation, noise) + the offset that
      makes the plain one the threshold, then the largest in its 3x3, and the strong
      pixels, above it (``LIMIT_AHEAD`` rows ahead);
    * the mask: pixels above the weak fraction of their threshold within the 5x5
      (ellipse) of a strong pixel; then what the frame teaches (``learn_row``);
    * which pixels stir: changed since the previous frame or since ``lagged``, a
      few frames before (``lagged``: an object creeping a fraction of a pixel a
      frame);
    * the ghost step (``absorb_ghosts_row``, ``GHOST_BEHIND`` rows behind).

    The raw motion (the difference above the plain threshold) goes to ``raw_out``;
    ``raw`` holds last frame's. While the scene is learned,
    flips deep inside a solid raw region (its 7x7) do not teach the variability;
    otherwise, where anything moved last frame, still pixels within the 7x7 of the
    last mask teach it at the near-motion rate.
    """
    images = Images(gray, previous_gray, lagged, previous_mask, difference, mask_out)
    model, state, rings = as_model(model_planes), as_state(state_planes), as_rings(ring_planes)
    rates, frame = Rates(*rate_values), FrameSettings(*frame_values)
    differing = -1
    if not learn_only:
        gains(
            gray,
            model.background,
            previous_mask,
            GAIN_GRID,
            frame.gain_limit,
            rates.frame_gain,
            rates.banded,
            row_gains,
        )
        differing = compare(
            gray, model, row_gains, rates.established_weight, frame.level, difference
        )
        if differing > frame.compare_only_above:
            return differing, -1
    stirred = state.stirred
    learning = frame.learning
    rows, cols = gray.shape
    level = frame.level
    k = rates.k
    noise_deviation = frame.noise_deviation
    offset = frame.threshold - k * noise_deviation
    row = np.empty(cols, np.uint8)
    grown = np.empty(cols, np.uint8)
    near_motion = np.zeros(cols, np.uint8)
    solid = np.zeros(cols, np.uint8)
    near_stirring = np.empty(cols, np.uint8)
    # Which rows hold anything: most rows of most frames hold nothing that moves, and
    # their neighbourhoods need no look.
    previous_rows = np.zeros(rows, np.bool_)
    if frame.near_motion_known:
        for y in range(rows):
            previous_rows[y] = holds_any(previous_mask[y])
    strong_rows = np.zeros(rows, np.bool_)
    moving_rows = np.zeros(rows, np.bool_)
    guarded_rows = np.zeros(rows, np.bool_)
    moving = 0
    for ahead in range(rows + LIMIT_AHEAD + GHOST_BEHIND):
        if ahead < rows:
            limit_row(model.deviation, ahead, noise_deviation, k, offset, rings.limit[ahead % RING])
            above_row(difference, ahead, level, raw_out)
        pixel = ahead - 1  # Each pixel's threshold and the strong pixels: the 3x3 is known.
        if 0 <= pixel < rows:
            # Leaves and edges shift by a pixel or so, so a neighbour's variability is a
            # pixel's own a moment later: its threshold is the largest in its 3x3.
            column_extreme(rings.limit, pixel, 1, rows, True, row)
            per_pixel = rings.per_pixel[pixel % RING]
            spread_row(row, 1, True, per_pixel)
            strong = rings.strong[pixel % RING]
            above_each_row(difference[pixel], per_pixel, strong)
            strong_rows[pixel] = holds_any(strong)
        learned = ahead - LIMIT_AHEAD
        if 0 <= learned < rows:
            # Hysteresis: pixels above half their threshold count where a strong one
            # (above it) is near, so low-contrast objects come out whole and weak
            # noise stays out.
            if any_near(strong_rows, learned, 2):
                # The strong pixels' 5x5 ellipse: 5 wide over 3 rows, and the middle
                # column over 5.
                column_extreme(rings.strong, learned, 1, rows, True, row)
                spread_row(row, 2, True, grown)
                column_extreme(rings.strong, learned, 2, rows, True, row)
                merge_row(row, True, grown)
            else:
                grown[:] = 0
            if learning:
                # While the scene is learned, a flip deep inside a solid region is an
                # object stepping in or a ghost uncovered, not a sway: it does not teach.
                column_extreme(raw_out, learned, LEARNING_REACH, rows, False, row)
                spread_row(row, LEARNING_REACH, False, solid)
            elif any_near(previous_rows, learned, LEARNING_REACH):
                # Still pixels next to the last frame's motion may be an object's
                # unseen parts: they teach the variability slowly.
                column_extreme(previous_mask, learned, LEARNING_REACH, rows, True, row)
                spread_row(row, LEARNING_REACH, True, near_motion)
            else:
                near_motion[:] = 0
            learn_row(
                images,
                model,
                state.settled,
                raw,
                raw_out,
                rings,
                grown,
                solid,
                near_motion,
                row_gains[learned],
                level,
                not learning,
                rates.weak_fraction,
                rates.established_weight,
                rates.seed_weight,
                rates.learning_rate,
                rates.mode_rate,
                frame.deviation_rate,
                rates.near_motion_rate,
                rates.moving_rate,
                learned,
            )
            count = count_above(mask_out, learned, np.float32(0.0))
            moving += count
            moving_rows[learned] = count > 0
            stirring_row(
                gray,
                lagged,
                rings.changing[learned % RING],
                level,
                frame.guard_frames,
                state.stirring,
                stirred,
                learned,
            )
            guarded_rows[learned] = holds_any(stirred[learned])
        ghost = learned - GHOST_BEHIND
        if rates.ghost_absorption and 0 <= ghost < rows and moving_rows[ghost]:
            if any_near(guarded_rows, ghost, GUARD_REACH):
                column_extreme(stirred, ghost, GUARD_REACH, rows, True, row)
                spread_row(row, GUARD_REACH, True, near_stirring)
            else:
                near_stirring[:] = 0
            absorb_ghosts_row(
                gray,
                mask_out,
                rings.changing[ghost % RING],
                near_stirring,
                state.kept,
                rings.rounded,
                state.settled,
                ghost,
                frame.reach,
                frame.settle_frames,
                frame.margin,
                model.background,
            )
    return differing, moving
