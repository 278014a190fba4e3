"""What a frame teaches the model, per pixel: compiled row functions of the step.

* **Two modes** — each pixel keeps an alternate value beside its main one (a cheap
  two-mode mixture, after Stauffer and Grimson, 1999): leaf against sky, an edge that
  a shaking camera moves back and forth. A frame is compared with the nearer mode
  (``compare``). The alternate counts as background once it *recurs*: its weight grows
  only on frames that match it right after a background frame, so a stopped object,
  which stays foreground, never earns one (still-region absorption handles it
  instead). A value far from both modes takes the place of a weak alternate, but gets
  a fresh weight only right after a background frame too: a passing object's inside,
  replacing it frame after frame, leaves it to fade.
* **Selective update** — pixels that move do not teach the background (a running
  average, as Motion's and OpenCV's ``accumulateWeighted``), so a slow, uniform
  object is not absorbed while it crosses (frame difference's weak spot).
* **Per-pixel variability** — each pixel keeps its mean deviation from the
  background, learned from still pixels and from pixels whose detection flips (the
  blink of SuBSENSE, St-Charles et al., 2015), clipped at its own threshold so one
  passing object cannot inflate it (``threshold`` turns it into the pixel's own
  threshold). While the scene is learned the deviation is the plain, unclipped mean
  of its samples, so a sway is known after one swing, and flips deep inside a solid
  changed region (an object stepping in, a ghost uncovered) do not count. Afterwards,
  still pixels right next to motion teach it at a fraction of the rate: they may be
  the parts of a camouflaged object that match the background, and a slow one would
  otherwise teach its own pixels deaf, then vanish piece by piece.

Models (never negative) are rounded to grey levels as OpenCV's ``saturate_cast``
rounds (to nearest, halves to even, at most 255). The arithmetic is float32 (whole
grey levels are exact in it) and branch-free where it can be (selects rather than
if), so the loops vectorise eight pixels at a time.
"""

from __future__ import annotations

import numpy as np

from app.vision.compiled import compiled_helper
from app.vision.motion.adaptive.model import Images, Model, Rings
from app.vision.motion.adaptive.rows import RING, count_above
from app.vision.types import FloatImage, GrayImage, Mask

MAX_GREY = np.float32(255.0)

LEAST_SIGNIFICANT = np.float32(1e-3)
"""A weight or deviation that decays below this is zero: it means nothing by then, and
left to decay it would reach float32's subnormal range (after about 90 s for an
alternate's weight) and stick there, where each operation costs many times a normal
one's: the real clip's model cost a fifth more per frame after ten minutes
(``bench_pipeline.py`` (e)), and twice as much with two pixels in five stuck."""


@compiled_helper
def compare(
    gray: GrayImage,
    model: Model,
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
            model.background,
            model.alternate,
            model.weight,
            gains[y],
            established_weight,
            difference_out,
            y,
        )
        moving += count_above(difference_out, y, level)
    return moving


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
        main = mode_difference(shade, background[y, x], gain)
        other = mode_difference(shade, alternate[y, x], gain)
        use_other = (other < main) & (weight[y, x] >= established_weight)
        out[y, x] = np.uint8(other if use_other else main)


@compiled_helper
def mode_difference(shade: np.float32, mode: np.float32, gain: np.float32) -> np.float32:
    """|shade - mode x gain|, the mode rounded to a grey level."""
    return abs(shade - min(np.rint(mode * gain), MAX_GREY))


@compiled_helper
def learn_row(
    images: Images,
    model: Model,
    settled: np.ndarray,
    previous_raw: Mask,
    raw: Mask,
    rings: Rings,
    grown_strong: Mask,
    solid: Mask,
    near_motion: Mask,
    gain: np.float32,
    level: np.float32,
    clip_deviation: bool,
    weak_fraction: np.float32,
    established_weight: np.float32,
    seed: np.float32,
    lr: np.float32,
    mr: np.float32,
    dr: np.float32,
    near_rate: np.float32,
    moving_rate: np.float32,
    y: int,
) -> None:
    """Row ``y``'s mask (hysteresis), then every model update it makes.

    Per pixel: moving = difference above the weak fraction of its own threshold
    (``rings.per_pixel``) and within reach of a strong pixel (``grown_strong``);
    still pixels and flips of the raw motion (``raw`` against ``previous_raw``)
    not inside a ``solid`` region teach the variability (at rate
    ``dr``, clipped at the pixel's threshold with ``clip_deviation``), still pixels
    ``near_motion`` that do not flip at ``near_rate``; a still pixel teaches its
    nearer mode at ``lr`` (a moving pixel at ``moving_rate``: none where the update is
    selective);
    an alternate that matches right after a background frame gains weight (at
    ``mr``; it counts from ``established_weight``), and a value far from both modes
    replaces a weak alternate (with a fresh weight, ``seed``, only right after a
    background frame). Counts, per pixel, the frames it has been still
    (``settled``, at most 255), and writes, for the ghost step, the pixels
    that changed since the previous frame (``rings.changing``) and the background
    rounded to grey levels (``rings.rounded``). ``grown_strong``, ``solid`` and
    ``near_motion`` are rows; ``gain`` the row's.
    """
    # The scalars come as arguments: in a tuple (``Rates``), they slowed this loop by a
    # quarter (bench/revision_speed.py).
    gray, previous_gray, previous_mask = images.gray, images.previous_gray, images.previous_mask
    difference, mask_out = images.difference, images.mask
    background, alternate = model.background, model.alternate
    weight, deviation = model.weight, model.deviation
    at = y % RING
    per_pixel, changing_out, rounded_out = (
        rings.per_pixel[at],
        rings.changing[at],
        rings.rounded[at],
    )
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
        model_value = background[y, x]
        other = alternate[y, x]
        # The mode differences, as ``compare`` found them.
        main_difference = mode_difference(shade, model_value, gain)
        other_difference = mode_difference(shade, other, gain)
        old_weight = weight[y, x]
        established = old_weight >= established_weight
        nearer_alternate = established & (other_difference < main_difference)
        # A moving pixel teaches at ``moving_rate``: 0 where the update is selective.
        rate = lr if still else moving_rate
        if_taught = model_value + rate * (shade - model_value)
        model_value = model_value if nearer_alternate else if_taught
        background[y, x] = model_value
        other = other + rate * (shade - other) if nearer_alternate else other
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
        rounded_out[x] = np.uint8(min(np.rint(model_value), MAX_GREY))
