"""The empty scene, estimated from frames sampled ahead (offline) or just before (live).

A live camera must learn its scene from the first frame it sees: whatever
stands in view then becomes background, leaves a ghost where it stood when it
moves off, and is missed wherever it passes over its own first picture. A
recording can be looked ahead in. Frames sampled evenly over its first seconds
show each pixel both with and without the objects that pass it, and the
background is estimated from them:

* **Both ends** — the median of the first few samples (the start) and of the
  last few (the end) each hide what moves through quickly. Where the two agree,
  the pixel shows the scene at both ends (the start's picture is taken), however
  long something covered it in between (a slow car covers the middle of its
  path most of the time: a median over all samples would take the car for the
  scene there).
* **Where they disagree** something stood at one end, or the light changed.
  Per region of disagreement, the end whose picture continues its
  surroundings is the scene: an object's outline is an edge across the
  region's border, the scene behind it is not (the test the adaptive model
  uses for ghosts). Where neither end's picture changes sharply there (a
  cloud's shadow moved on; a lamp came on), or the end is the same ground in
  another light (its fine texture unchanged), the start's picture is: it is
  what the first frame shows. A region too small to tell by its border takes the
  median of all samples.
* **The view changed** (a light switched, the camera was moved, something
  came to fill it) where a later run of samples differs from the start over
  much of the picture: only the samples up to the change count (the search by
  halving may keep a sample or two past it, which the medians outvote), and
  the model's own light-switch and knock handling take the change when it
  comes.

Each pixel's variability (its mean deviation from the background while it
shows it) comes from the spread of the end samples that show the background
there, each end about its own median (a robust median deviation, so a sample
with an object passing does not count, nor does light that drifted between the
ends): leaves that sway are known from the first frame on.

A live camera cannot look ahead, but it can look back: it keeps a grey frame
now and then, and at Activate the median of the last few is the
scene (``estimate_recent_scene``): what walked through them is not in it, what
stands still is, and nobody in view when Activate is pressed leaves a ghost.
Where the newest few (the frame at Activate among them) show the same ground
in another light (its fine texture unchanged: a lamp came on), that is the
scene there; anything else they agree on may be someone who stopped a moment
ago, and is left to the model.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Generic, TypeVar

import cv2
import numpy as np

from app.vision.noise import HALF_NORMAL_MEDIAN
from app.vision.types import FloatImage, GrayImage
from app.vision.view_shift import moved_view

END_SAMPLES = 5
"""Samples at each end of the sampled stretch whose median shows that end."""

LEAST_SAMPLES = 2 * END_SAMPLES
"""Fewer samples than this tell nothing of the ends: no estimate."""

LEAST_AGREEMENT = 12.0
"""Grey levels: the ends' medians within this of each other (or within three standard
deviations of the camera's noise, where that is more) show the same scene."""

MEAN_ABS_PER_MEDIAN_ABS = 0.7979 / HALF_NORMAL_MEDIAN
"""E|X| / median(|X|) for Gaussian X: a robust mean deviation from a median one."""

VIEW_CHANGED_SHARE = 0.25
"""Samples differing from the start over more than this share of the picture: the view
itself changed."""

CAMERA_MOVED_PX = 1.5
"""Pixels: samples whose picture is the start's shifted this far show a camera that moved."""

RECENT_SAMPLES = 3
"""The newest samples whose median shows the scene as it is now (a live camera's)."""

RELIT_CORRELATION = 0.9
"""A region whose newest picture's fine texture correlates with the older one's at least
this much is the same scene in another light (the adaptive model's test of a stale
region); an object, textured or plain, hides the ground's texture."""

TEXTURE_BAND = (1.0, 4.0)
"""Pixels: a picture's texture is its blur by the first less its blur by the second, the
detail between the camera's noise and a light's soft fall-off, which the light keeps.
(Where the camera's noise is 6 grey levels, a lamp's texture correlates 0.98 with the
ground's, and objects', plain or textured, -0.12 to 0.17; unblurred, the lamp's 0.85.)"""

SHARP_BORDER = 2.5
"""An end shows an outline along a region's border where its edges there (Sobel) reach
this many times the mean difference D between the ends just inside the border (where an
outline is; a car's rim may step little, its windows much): the change happens within a
pixel or two (a clean step of D gives about 4 D along the border; objects' blurred
outlines in the synthetic scenes 4.6 to 8.3 D, CDnet's swaying leaves 3.7 to 20 D). A
cloud's shadow, a lamp's pool, spread their change over tens of pixels (0.7 to 1.5 D)..."""

ONE_SIDED = 3.0
"""... or where its edges there are this many times the other end's: an outline, if a
soft one (an object half blended into the samples' median), beside plain ground. A
cloud's shadow's edge is as soft in both ends (0.5 to 2 times)."""

LEAST_REGION = 16
"""Pixels: a region of disagreement smaller than this has no border to judge it by."""

T = TypeVar("T")


@dataclass(frozen=True)
class SceneBackground:
    """What a clip shows where nothing moves, at the size detection runs at."""

    background: FloatImage
    """Grey levels, float32."""
    variability: FloatImage
    """Each pixel's mean |frame - background| while it shows the background, float32."""
    view_changed: bool
    """The view changed within the samples: the background is from those before."""


class EvenSample(Generic[T]):
    """At most ``2 x size - 1`` items spread evenly over a stream of unknown length (at
    least ``size`` once that many have passed): every ``stride``-th, the stride doubling
    (and every other item kept dropped) whenever twice ``size`` are held."""

    def __init__(self, size: int) -> None:
        if size < 1:
            raise ValueError(f"a sample holds at least one item, not {size}")
        self.size = size
        self.items: list[T] = []
        self.stride = 1
        self.offered = 0

    def offer(self, make: Callable[[], T]) -> None:
        """The stream's next item; ``make`` builds it, called only where it is kept."""
        if self.offered % self.stride == 0:
            self.items.append(make())
            if len(self.items) == 2 * self.size:
                self.items = self.items[::2]
                self.stride *= 2
        self.offered += 1


def estimate_scene_background(samples: Sequence[GrayImage]) -> SceneBackground | None:
    """The background and its variability from grey frames sampled in order over a clip
    (all one size); None where there are fewer than ``LEAST_SAMPLES``."""
    if len(samples) < LEAST_SAMPLES:
        return None
    stack = np.stack(samples)  # 8-bit: a clip's samples at full size are large.
    start = _median(stack[:END_SAMPLES])
    # The camera's noise, from how far the start's samples stray from their median (the
    # ends' medians differ by less than a sample does).
    strays = np.abs(stack[:END_SAMPLES].astype(np.float32) - start)
    agreement = _agreement(float(np.median(strays)))
    same_view = _same_view(stack, start, agreement)
    view_changed = same_view < len(stack)
    stack = stack[:same_view]
    end = _median(stack[-END_SAMPLES:])
    disagree = np.abs(start - end) > agreement
    # The same ground in another light at the end (a cloud's shadow moved, a lamp came
    # on) is the scene at both: the start's picture, as where the ends agree.
    disagree &= ~_relit(start, end, disagree)
    background, shows_start = _pick_ends(start, end, disagree, stack)
    # Each end's spread about its own median (a drift between them is no sway); where
    # the ends agree, both show the scene, elsewhere only the end chosen does.
    spread_start = _median_deviation(stack[:END_SAMPLES], start)
    spread_end = _median_deviation(stack[-END_SAMPLES:], end)
    deviation = np.where(
        disagree,
        np.where(shows_start, spread_start, spread_end),
        (spread_start + spread_end) / 2,
    )
    return SceneBackground(
        np.ascontiguousarray(background, np.float32),
        np.ascontiguousarray(MEAN_ABS_PER_MEDIAN_ABS * deviation, np.float32),
        view_changed,
    )


def estimate_recent_scene(
    samples: Sequence[GrayImage], now: GrayImage | None = None
) -> SceneBackground | None:
    """The scene as grey frames sampled over the last moments show it (a live camera's,
    at Activate, which cannot look ahead; the newest last), and ``now``, the frame at
    Activate: the samples' median, so what moved through them is not in it and what
    stood still is (a parked car is scene, not motion), and each pixel's median
    deviation from it as its variability. Where the median of the newest samples and
    ``now`` (``RECENT_SAMPLES`` in all) shows the same in another light (``_relit``: a
    lamp came on), that is the scene. None with fewer than ``END_SAMPLES`` samples, or
    where the newest (``now``) differs from the median over more than
    ``VIEW_CHANGED_SHARE`` of the picture (the view changed among them, or something big
    stands in it now: the model then learns the first frame, as without samples)."""
    if len(samples) < END_SAMPLES:
        return None
    stack = np.stack(samples)
    settled = _median(stack)
    deviation = _median_deviation(stack, settled)
    agreement = _agreement(float(np.median(deviation)))
    newest = (
        [*samples[-RECENT_SAMPLES + 1 :], now] if now is not None else samples[-RECENT_SAMPLES:]
    )
    if np.mean(np.abs(newest[-1] - settled) > agreement) > VIEW_CHANGED_SHARE:
        return None
    # Not in the median of all: two of them may be a moment apart, someone walking in both.
    recent = _median(np.stack(newest))
    difference = np.abs(recent - settled)
    # With its fringe (half as far, joined to it): a soft light's edge is relit too.
    changed = _grown(difference > agreement / 2, difference > agreement)
    relit = _relit(settled, recent, changed)
    background = np.where(relit, recent, settled)
    if relit.any():
        # Each sample about the scene it shows, before or after the light changed.
        either = np.minimum(np.abs(stack - settled), np.abs(stack - recent))
        deviation = np.where(relit, _median(either), deviation)
    return SceneBackground(
        np.ascontiguousarray(background, np.float32),
        np.ascontiguousarray(MEAN_ABS_PER_MEDIAN_ABS * deviation, np.float32),
        False,
    )


def _same_view(stack: np.ndarray, start: FloatImage, agreement: float) -> int:
    """How many samples, from the first, show the start's view: up to the last run of
    ``END_SAMPLES`` whose median differs from ``start`` by more than ``agreement`` over
    at most ``VIEW_CHANGED_SHARE`` of the picture and is not the start's picture shifted
    by up to ``PAN_REACH`` (a light that switched, a camera that moved, stays so:
    the run is sought by halving)."""

    def same(stop: int) -> bool:
        window = _median(stack[stop - END_SAMPLES : stop])
        if np.mean(np.abs(window - start) > agreement) > VIEW_CHANGED_SHARE:
            return False
        # A camera knocked a few pixels changes little more than the scene's edges: the
        # view shifted is sought, and taken where it explains the change.
        return moved_view(start, window, agreement, CAMERA_MOVED_PX) is None

    if same(len(stack)):
        return len(stack)
    agrees, differs = END_SAMPLES, len(stack)  # The start's own run agrees with itself.
    while differs - agrees > 1:
        middle = (agrees + differs) // 2
        agrees, differs = (middle, differs) if same(middle) else (agrees, middle)
    return agrees


def _pick_ends(
    start: FloatImage, end: FloatImage, disagree: np.ndarray, stack: np.ndarray
) -> tuple[FloatImage, np.ndarray]:
    """The background, and where it is the start's picture. Where the ends agree it is
    the start's: what the first frame shows (the light may have drifted a little by the
    end). Where they disagree, region by region, the end that continues the region's
    surroundings, where either end shows an outline along the region's border
    (``SHARP_BORDER``, ``ONE_SIDED``), else the start: a change of light (or the median
    of all samples, for a region too small to judge, where the start's spread stands for
    its variability)."""
    background = start.copy()
    shows_start = np.ones(start.shape, bool)
    regions, labels, stats, _ = cv2.connectedComponentsWithStats(
        disagree.astype(np.uint8), connectivity=8
    )
    if regions == 1:
        return background, shows_start
    edges_start, edges_end = _edges(start), _edges(end)
    overall: FloatImage | None = None
    ring = np.ones((3, 3), np.uint8)
    height, width = start.shape
    for region in range(1, regions):
        x, y, w, h, area = (int(v) for v in stats[region])
        rows = slice(max(y - 1, 0), min(y + h + 1, height))
        box = (rows, slice(max(x - 1, 0), min(x + w + 1, width)))
        inside = labels[box] == region
        if area < LEAST_REGION:
            if overall is None:
                overall = _median(stack)
            background[box][inside] = overall[box][inside]
            continue
        shape = inside.astype(np.uint8)
        border = cv2.dilate(shape, ring) != cv2.erode(shape, ring)
        along_start = edges_start[box][border].mean()
        along_end = edges_end[box][border].mean()
        sharper, softer = max(along_start, along_end), min(along_start, along_end)
        contrast = np.abs(start[box] - end[box])[border & inside].mean()
        outline = sharper >= SHARP_BORDER * contrast or sharper >= ONE_SIDED * softer
        take_end = outline and along_end < along_start
        chosen = end if take_end else start
        background[box][inside] = chosen[box][inside]
        shows_start[box][inside] = not take_end
    return background, shows_start


def _relit(before: FloatImage, after: FloatImage, changed: np.ndarray) -> np.ndarray:
    """The regions of ``changed`` where ``after`` is ``before`` in another light: their
    fine textures correlate by ``RELIT_CORRELATION`` or more. None too thin to tell
    (under ``LEAST_REGION`` pixels more than 2 from its edge): a strip along an object's
    outline, where it stood a moment apart, shares the outline's blur."""
    regions, labels = cv2.connectedComponents(changed.astype(np.uint8), connectivity=8)
    relit = np.zeros(regions, bool)
    if regions > 1:
        texture_before, texture_after = _texture(before), _texture(after)
        core = cv2.erode(changed.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
        thick = np.bincount(labels[core], minlength=regions) >= LEAST_REGION
        for region in np.flatnonzero(thick[1:]) + 1:
            inside = labels == region
            a, b = texture_before[inside], texture_after[inside]
            spread = float(a.std()) * float(b.std())
            if spread > 0.0:
                together = float(np.mean((a - a.mean()) * (b - b.mean()))) / spread
                relit[region] = together >= RELIT_CORRELATION
    return relit[labels]


def _texture(image: FloatImage) -> FloatImage:
    """The detail of ``image`` that a soft light keeps (``TEXTURE_BAND``)."""
    fine, coarse = TEXTURE_BAND
    return cv2.GaussianBlur(image, (0, 0), fine) - cv2.GaussianBlur(image, (0, 0), coarse)


def _grown(weak: np.ndarray, strong: np.ndarray) -> np.ndarray:
    """The regions of ``weak`` that hold a pixel of ``strong`` (a subset of weak)."""
    regions, labels = cv2.connectedComponents(weak.astype(np.uint8), connectivity=8)
    holds_strong = np.zeros(regions, bool)
    holds_strong[labels[strong]] = True
    holds_strong[0] = False
    return holds_strong[labels]


def _agreement(median_stray: float) -> float:
    """Grey levels within which two medians show the same scene, from the median of
    samples' distances to their median (``LEAST_AGREEMENT``, or three standard deviations
    of the noise that median shows, where that is more)."""
    return max(LEAST_AGREEMENT, 3.0 * median_stray / HALF_NORMAL_MEDIAN)


def _median(frames: np.ndarray) -> FloatImage:
    """The per-pixel median of a stack of frames, float32."""
    return np.median(frames, axis=0).astype(np.float32)


def _median_deviation(frames: np.ndarray, center: FloatImage) -> FloatImage:
    """The per-pixel median of |frame - center| over a stack of frames, float32."""
    return _median(np.abs(frames.astype(np.float32) - center))


def _edges(image: FloatImage) -> FloatImage:
    """How sharply the grey level steps at each pixel (Sobel, |dx| + |dy|)."""
    dx = cv2.Sobel(image, cv2.CV_32F, 1, 0, ksize=3)
    dy = cv2.Sobel(image, cv2.CV_32F, 0, 1, ksize=3)
    return np.abs(dx) + np.abs(dy)
