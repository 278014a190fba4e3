"""Still regions: what stays "moving" without any change becomes background, but for
objects that stopped, which are kept whole.

Every ``check_every`` frames each motion region counts the frames it went without any
change, from frame to frame or over ``check_every`` frames (a ghost or a stopped
object, not one creeping a fraction of a pixel a frame). A stale region becomes
background after ``relit_after`` frames where it is no object: the frame there is the
background in another light (it correlates with it: a lamp came on, a shadow fell), or
a ghost (across the region's border the frame steps less than the background does).
**An object that stopped** (a person waiting) stays for ``absorb_after`` frames (5 s at
25 fps), kept whole, out of the ghost step's reach, where its outline is clearly an
object's, and stays kept while it stays still. **A region that moves with most of its
inside unchanged** (a lorry's plain side, something creeping), seen so at two checks
running, is kept whole too: the ghost step would eat it from the rim in, where the
rim happens to match the ground.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from app.vision.compiled import compiled
from app.vision.mask_box import motion_box
from app.vision.motion.adaptive.model import ON_THE_MOVE, SEEN_MOVING, STOPPED, State
from app.vision.types import FloatImage, GrayImage, Mask

RELIT_CORRELATION = 0.9
"""A stale region whose frame correlates with its background at least this much is the
scene in another light, absorbed after ``relit_after`` frames (camera noise alone keeps a
faintly textured patch below it: such a patch waits ``absorb_after``)."""

LEAST_PATTERN = 25
"""Pixels: a stale region smaller than this (a 5x5 patch) shows no pattern to tell an
object by, and is absorbed after ``relit_after`` frames (the specks a lamp leaves)."""

CLEAR_EDGE = 1.75
"""A stopped object is kept whole (out of the ghost step's reach) where the frame steps
across its border at least this many times as much as the background does: clearly an
object's outline, not a ghost's that happens to run along the scene's own edges (a
ghost's frame steps less than its background). A person whose clothes are 40 grey levels
from a textured ground's mean measured 1.5 to 2 at the first check after they stopped;
at 1.5, a soft spot of lamplight on such ground was sometimes kept too (for
``absorb_after`` frames)."""

QUIET_INSIDE = 0.3
"""The largest share of a moving region's pixels that may stir for the ghost step to
leave it whole: most of it unchanged, it is an object whose inside does not change as
it moves, which the ghost step would take for a ghost from the rim in. A region mostly
astir (leaves, a walker) is left to the guard of each stirring pixel: kept whole,
swaying leaves stayed motion (CDnet fall's F, over all frames with the scan, fell from
0.910 to 0.887 with every region on the move kept; with this share, and two checks
running, it stays 0.910)."""


def absorb_still_regions(
    gray: GrayImage,
    mask: Mask,
    state: State,
    still_frames: np.ndarray,
    background: FloatImage,
    check_every: int,
    absorb_after: int,
    relit_after: int,
    keep_stopped: bool,
    keep_moving: bool,
) -> None:
    """Count, per motion region of ``mask``, frames without any change (by
    ``check_every``, in ``still_frames``); absorb the stale ones into ``background``;
    with ``keep_stopped``, keep whole those that stopped and look like objects; with
    ``keep_moving``, those on the move with an unchanging inside."""
    # Regions are sought in the box of the mask's pixels only, with a pixel of
    # background around them (their borders are measured): most of a frame holds
    # none. An empty mask gives a part of one pixel, and no region.
    rows, cols = motion_box(mask, 1) or (slice(0, 1), slice(0, 1))
    part = mask[rows, cols]
    # 16-bit labels (half the memory to sweep) where they surely suffice: 8-connected
    # regions are at most a quarter of the pixels (lone pixels, one apart).
    wide = part.size // 4 >= 2**16 - 1
    regions, labels = cv2.connectedComponents(
        part, connectivity=8, ltype=cv2.CV_32S if wide else cv2.CV_16U
    )
    age_still_regions(
        labels,
        rows.start,
        cols.start,
        regions,
        state.stirring,
        gray,
        check_every,
        absorb_after,
        relit_after,
        RELIT_CORRELATION,
        LEAST_PATTERN,
        CLEAR_EDGE if keep_stopped else math.inf,
        keep_moving,
        still_frames,
        background,
        state.kept,
    )


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
