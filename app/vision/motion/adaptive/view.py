"""Following the view: a camera that is knocked, shakes or turns (a pan).

Where much of the view turns "moving" at once and is no light switch, the shift of
the scene in the picture is sought (template matching of the frame's middle against
the background). If the background moved by it explains the change, the whole model
moves with the scene and the frame is compared again, so what moves in it is still
found and the scene is not reported as motion. A shaking camera is followed frame by
frame, and one that turns every few frames: the change is sudden against the calm of
the last half second (``ViewWatch``), and once the view has been followed, a little
change is enough to seek it again. A very slow pan, a turn about the lens axis or a
zoom is not followed (still-region absorption handles them), nor is a shift that
shows in too few parts of the view to tell (``view_shift``): on a plain wall, an
object's own move explains the change as well as a moved view would.
"""

from __future__ import annotations

import math
from collections import deque

import cv2
import numpy as np

from app.vision.motion.adaptive.gains import GAIN_GRID
from app.vision.motion.adaptive.model import Model
from app.vision.motion.base import in_frames
from app.vision.types import FloatImage, GrayImage
from app.vision.view_shift import VIEW_SHIFT_REACH, shift_explains, shifted

CAMERA_MOVE_SHARE = 0.05
"""The share of the frame that must turn "moving" (and ``SUDDEN_GROWTH`` times the least
of the last ``CALM_FRAMES``) for the camera to be suspected of having moved: a knock of a
pixel or two changes little more than the scene's edges, a tenth of a street scene."""

SUDDEN_GROWTH = 2.0
"""How many times the least raw motion of the last ``CALM_FRAMES`` a frame must have for
the change to count as sudden (with ``CAMERA_MOVE_SHARE``): what a knock does, and a
camera turning does within a few frames, where a busy street's moving share stays put."""

CALM_FRAMES = 12
"""Frames (at 25 fps) back to the calm that a sudden change is measured against. Against
last frame's alone, a pan of 2.4 px a frame was never followed: the change it makes
grows frame by frame, never twice as much as the frame before's. Against every frame's
(no growth asked), the view was sought on a fifth of a busy street's frames."""

FOLLOWING_SHARE = 0.01
"""The share of the frame that, for ``CALM_FRAMES`` after the view was followed, must turn
"moving" (of a sudden or not) for it to be sought again: the camera may be turning, and
the change it makes grows from nothing after each follow. With ``CAMERA_MOVE_SHARE`` and
the sudden growth asked, a pan of 2.4 px a frame was followed every 8 to 10 frames, its
edges reported as objects in between, and a strip left for seconds after it stopped."""

SEARCH_BACKOFF = 6
"""Frames (at 25 fps) after a search for a moved view that found none (something big
moving, not the camera) before the next: a busy street's big objects asked for one on 15%
of its frames, 0.7 ms each."""

LEARNING_CAMERA_MOVE_SHARE = 0.2
"""``CAMERA_MOVE_SHARE`` while the scene is being learned: the model is then little more
than the first frame, which much of the view may differ from for other reasons (what
was in view then, leaves whose sway is not known yet)."""

CAMERA_MATCH_WIDTH = 320
"""Pixels: a frame N >= 2 times this wide is reduced N times to seek the shift (the
matching's cost grows with the frame's area); the shift is checked at full size."""

CAMERA_MOVE_LEAST = 0.5
"""Pixels: the least shift of the view taken for a camera that moved."""


class ViewWatch:
    """When a frame's change is sudden enough for the view to be sought (``sudden``),
    from the raw motion of the last frames and the searches made lately."""

    def __init__(self, fps: float) -> None:
        self._calm: deque[int] = deque()
        """Pixels of raw motion in each of the last ``CALM_FRAMES`` (scaled) frames."""
        self._next_search = 0
        """The first frame on which a moved view may be sought again (``SEARCH_BACKOFF``)."""
        self._following_until = 0
        """The frame until which the view may still be moving (``FOLLOWING_SHARE``)."""
        self.set_fps(fps)

    def set_fps(self, fps: float) -> None:
        self._calm_frames = in_frames(CALM_FRAMES, fps)
        self._search_backoff = in_frames(SEARCH_BACKOFF, fps)
        if self._calm.maxlen != self._calm_frames:
            self._calm = deque(self._calm, maxlen=self._calm_frames)

    def reset(self) -> None:
        self._calm.clear()
        self._next_search = self._following_until = 0

    def sudden(self, frame_index: int, learning: bool, pixels: int) -> float:
        """The pixels of raw motion past which this frame's change is sudden enough for
        the view to be sought (infinite while a search that found none backs off)."""
        if frame_index < self._next_search:
            return math.inf  # A search just found the view where it was.
        if frame_index < self._following_until and not learning:
            return FOLLOWING_SHARE * pixels
        share = LEARNING_CAMERA_MOVE_SHARE if learning else CAMERA_MOVE_SHARE
        return max(share * pixels, SUDDEN_GROWTH * min(self._calm, default=0))

    def followed(self, frame_index: int) -> None:
        """The view was followed on this frame: it may still be moving on the next ones."""
        self._following_until = frame_index + 1 + self._calm_frames

    def not_found(self, frame_index: int) -> None:
        """A search on this frame found no moved view."""
        if frame_index >= self._following_until:
            # Not while following: a view that moved less than a step since is sought
            # again on the next frame.
            self._next_search = frame_index + 1 + self._search_backoff

    def note(self, changed: int) -> None:
        """This frame's raw motion, in pixels."""
        self._calm.append(changed)


def scene_shift(
    background: FloatImage, gray: GrayImage, threshold: float
) -> tuple[float, float] | None:
    """How far (x, y pixels) the scene moved in the picture, where the camera was
    knocked (the other way): the shift, up to ``VIEW_SHIFT_REACH``, by which the
    background best matches the frame, provided that the background moved that far
    explains the change (``view_shift.shift_explains``). None where no shift does:
    something big stepped into view. A wide frame is matched at a reduced size
    (``CAMERA_MATCH_WIDTH``), and first at half that (``_matched_shift``)."""
    height, width = gray.shape
    frame = gray.astype(np.float32)
    reduce = max(1, width // CAMERA_MATCH_WIDTH)
    size = (width // reduce, height // reduce)
    reduced_background = cv2.resize(background, size, interpolation=cv2.INTER_AREA)
    picture = cv2.resize(frame, size, interpolation=cv2.INTER_AREA)
    reach = max(2, round(VIEW_SHIFT_REACH * size[0]))
    if min(size) <= 4 * reach:
        return None
    dx, dy = (reduce * shift for shift in _matched_shift(reduced_background, picture, reach))
    if math.hypot(dx, dy) < CAMERA_MOVE_LEAST:
        return None
    # Checked on a grid, as the gain is measured.
    explained = shift_explains(background, frame, dx, dy, threshold, GAIN_GRID)
    return (dx, dy) if explained else None


def follow_scene(
    model: Model,
    counts: tuple[np.ndarray, ...],
    gray: GrayImage,
    threshold: float,
    dx: float,
    dy: float,
) -> None:
    """Move the whole model and the per-pixel ``counts`` and masks kept from frame to frame
    (dx, dy) pixels with the scene, so
    that only what moves in it is motion. The strip that came into view takes this
    frame as its background, with nothing learned about it yet (no alternate, no
    variability, not settled, never still). Where the moved background explains the
    frame, the frame is taken as the background: it is the sharper picture of the
    scene (resampling blurs, and a camera knocked again and again would blur the
    background until its edges were motion)."""
    frame = gray.astype(np.float32)
    background = shifted(model.background, dx, dy, frame.copy())
    explained = np.abs(frame - background) <= threshold
    background[explained] = frame[explained]
    model.background[...] = background
    model.alternate[...] = shifted(model.alternate, dx, dy, frame.copy())
    for plane in (model.weight, model.deviation):
        plane[...] = moved(plane, dx, dy)
    for plane in counts:
        plane[...] = moved(plane, dx, dy, smooth=False)


def moved(image: np.ndarray, dx: float, dy: float, smooth: bool = True) -> np.ndarray:
    """``image`` moved (dx, dy) pixels, 0 where nothing of it lands."""
    return shifted(image, dx, dy, np.zeros_like(image), smooth)


def _matched_shift(background: FloatImage, picture: FloatImage, reach: int) -> tuple[float, float]:
    """The shift (x, y pixels, to a fraction of one), up to ``reach`` each way, by which
    ``background`` best matches ``picture``'s middle (all but ``reach`` pixels of each
    edge), by the least squared difference: sought over every shift on both halved, then
    from twice the shift found there down the slope at full size. One matching over every
    shift took 1.4 ms at 320x240, the halved one and the descent 0.6 (a mean over a busy
    street's frames): the view is sought on every frame where much of it changes of a
    sudden (``CALM_FRAMES``)."""
    height, width = picture.shape
    half, half_reach = (width // 2, height // 2), reach // 2
    if half_reach < 2 or min(half) <= 4 * half_reach:
        return _searched_shift(background, picture, reach)
    coarse = _searched_shift(
        cv2.resize(background, half, interpolation=cv2.INTER_AREA),
        cv2.resize(picture, half, interpolation=cv2.INTER_AREA),
        half_reach,
    )
    return _descended_shift(background, picture, reach, round(2 * coarse[0]), round(2 * coarse[1]))


def _searched_shift(background: FloatImage, picture: FloatImage, reach: int) -> tuple[float, float]:
    """``_matched_shift`` over every shift up to ``reach``, in one matching."""
    # Where the frame's middle fits in the background: a squared difference per shift.
    misfit = cv2.matchTemplate(background, picture[reach:-reach, reach:-reach], cv2.TM_SQDIFF)
    _, _, (left, top), _ = cv2.minMaxLoc(misfit)
    dx = reach - (left + _vertex_offset(misfit[top, left - 1 : left + 2]))
    dy = reach - (top + _vertex_offset(misfit[top - 1 : top + 2, left]))
    return dx, dy


def _descended_shift(
    background: FloatImage, picture: FloatImage, reach: int, dx: int, dy: int
) -> tuple[float, float]:
    """``_matched_shift`` from the whole-pixel shift (dx, dy): to the neighbouring shift
    that fits better while one does, then to a fraction of a pixel between neighbours."""
    template = picture[reach:-reach, reach:-reach]
    rows, cols = template.shape
    misfits: dict[tuple[int, int], float] = {}

    def misfit(x: int, y: int) -> float:
        if max(abs(x), abs(y)) > reach:
            return math.inf
        if (x, y) not in misfits:
            # The background moved (x, y) under the frame: its corner reach - shift in.
            part = background[reach - y : reach - y + rows, reach - x : reach - x + cols]
            misfits[x, y] = cv2.norm(part, template, cv2.NORM_L2SQR)
        return misfits[x, y]

    dx, dy = (max(-reach, min(reach, shift)) for shift in (dx, dy))
    while True:
        best = min(
            ((x, y) for x in (dx - 1, dx, dx + 1) for y in (dy - 1, dy, dy + 1)),
            key=lambda shift: misfit(*shift),
        )
        if best == (dx, dy) or misfit(*best) >= misfit(dx, dy):
            break
        dx, dy = best
    # Neighbours in the order of the background's corner (reach - shift), as matching has them.
    across = np.array([misfit(dx + 1, dy), misfit(dx, dy), misfit(dx - 1, dy)])
    down = np.array([misfit(dx, dy + 1), misfit(dx, dy), misfit(dx, dy - 1)])
    return dx - _vertex_offset(across), dy - _vertex_offset(down)


def _vertex_offset(values: np.ndarray) -> float:
    """Where, from the middle one (-0.5..0.5), the parabola through three values
    turns: a minimum's place between pixels. 0 at an edge of the search (fewer values,
    or one past the reach: infinite)."""
    if values.size != 3 or not np.isfinite(values).all():
        return 0.0
    before, middle, after = (float(v) for v in values)
    curvature = before - 2.0 * middle + after
    return 0.5 * (before - after) / curvature if curvature > 0 else 0.0
