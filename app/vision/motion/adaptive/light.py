"""Light switches, and relighting what was moving when the light changed.

A change that covers most of the scene, where nothing moved before too, and is
brighter (or darker) almost everywhere is re-learned at once instead of reported (a
lorry filling the view differs only where it drove in; a camera that shook differs as
widely, but both ways at each edge). Where something was moving then, the old
background is kept, relit by a line fitted locally from the old background to the new
frame, so an object in view stays an object. (Gradual changes of light, auto-exposure
and bands of mains light are the gain's work: ``gains``.)
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from app.vision.motion.adaptive.gains import GAIN_GRID
from app.vision.motion.adaptive.ghosts import GUARD_REACH
from app.vision.types import FloatImage, GrayImage, Mask

LIGHT_SPREAD = 16.0
"""Pixels: the standard deviation of the Gaussian window over which a light change is
fitted. A lamp's light changes over tens of pixels, and a window this wide reaches the
still pixels around an object some sixty pixels across."""

LIGHT_WINDOW_LEAST = 0.05
"""The least (weighted) share of still pixels a window needs for its own fit."""

_GUARD_KERNEL = np.ones((2 * GUARD_REACH + 1, 2 * GUARD_REACH + 1), np.uint8)


def lights_changed(
    gray: GrayImage,
    difference: GrayImage,
    threshold: float,
    background: FloatImage,
    previous_mask: Mask,
    switch_fraction: float,
) -> bool:
    """Whether a frame that differs from the background almost everywhere does so
    because the light changed (or the exposure jumped): it differs where nothing
    moved last frame too (on more than ``switch_fraction`` of those pixels), by more
    than ``threshold`` and the same way at most of those pixels (the median change).
    An object that fills the view differs only where it is, grown from where it was; a
    camera that shook differs everywhere, but brighter on one side of each edge and
    darker on the other."""
    grid = (slice(None, None, GAIN_GRID), slice(None, None, GAIN_GRID))
    was_still = previous_mask[grid] == 0
    if was_still.any():
        raw = difference[grid][was_still] > math.floor(threshold)
        changed = np.count_nonzero(raw) / np.count_nonzero(was_still)
        if changed <= switch_fraction:
            return False
    shift = np.median(gray[grid].astype(np.float32) - background[grid])
    return bool(abs(shift) > threshold)


def objects_in_view(moving: Mask, switch_fraction: float) -> Mask | None:
    """Where objects moving when the light changed may be now: the last mask widened by
    ``GUARD_REACH`` (for the step they took since). None where that covers as much of
    the frame as a light switch does: the "motion" was the light coming on over a few
    frames, not objects."""
    kept = cv2.dilate(moving, _GUARD_KERNEL)
    return None if cv2.countNonZero(kept) > switch_fraction * kept.size else kept


def relit(background: FloatImage, frame: GrayImage, still: np.ndarray, ridge: float) -> FloatImage:
    """``background`` as it looks in the light of ``frame``: fitted, around each pixel,
    by a straight line from the background to the frame over the ``still`` pixels
    nearby (a Gaussian window, ``LIGHT_SPREAD``): lamps add light and exposure scales it,
    each unevenly over the scene. A window whose (weighted) share of still pixels is
    under ``LIGHT_WINDOW_LEAST`` takes the fit over the whole frame instead; with no
    still pixel at all, the frame is all there is. ``ridge``, a variance of the
    background that the slope does not trust, pulls it towards the ratio of the means
    where the background is flat (any slope fits a flat patch)."""
    if not still.any():
        return frame.astype(np.float32)
    weight = still.astype(np.float32)
    old = background.astype(np.float32)
    new = frame.astype(np.float32)
    nearby = cv2.GaussianBlur(weight, (0, 0), LIGHT_SPREAD)

    def local_mean(term: FloatImage) -> FloatImage:
        return np.asarray(
            cv2.GaussianBlur(term * weight, (0, 0), LIGHT_SPREAD) / np.maximum(nearby, 1e-6)
        )

    def mean(term: FloatImage) -> float:
        return float((term * weight).sum() / weight.sum())

    terms = (old, new, old * old, old * new)
    fitted = np.where(
        nearby >= LIGHT_WINDOW_LEAST,
        _mapped_by_line(old, [local_mean(term) for term in terms], ridge),
        _mapped_by_line(old, [mean(term) for term in terms], ridge),
    )
    return np.clip(fitted, 0.0, 255.0).astype(np.float32)


def _mapped_by_line(
    old: FloatImage, means: Sequence[FloatImage] | Sequence[float], ridge: float
) -> FloatImage:
    """``old`` through the least-squares line from old to new given by the (weighted)
    means of old, new, old squared and old x new, its slope pulled towards the ratio of
    the means by ``ridge``."""
    old_mean, new_mean, old_square_mean, cross_mean = means
    variance = np.maximum(old_square_mean - old_mean * old_mean, 0.0)
    ratio = new_mean / np.maximum(old_mean, 1.0)
    slope = (cross_mean - old_mean * new_mean + ridge * ratio) / (variance + ridge)
    return np.asarray(new_mean + slope * (old - old_mean), np.float32)
