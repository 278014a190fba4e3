"""What the adaptive model keeps from frame to frame, and what the compiled step is
told each frame: named structures (Numba takes named tuples).

The model's and the state's planes are each one stacked buffer, allocated once per
view size and reused (fresh large buffers cost page faults on every frame); the named
tuples are views of them (``Model(*planes)`` in Python, ``as_model(planes)`` in the
compiled step). What crosses from Python into the step is buffers and plain tuples:
Numba takes a named tuple's type on each call in Python, which cost a paced frame
60 us more (bench/revision_speed.py)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from app.vision.compiled import compiled_helper
from app.vision.motion.adaptive.rows import RING
from app.vision.types import FloatImage, GrayImage, Mask


class Images(NamedTuple):
    """One frame's images, as the step reads and writes them."""

    gray: GrayImage
    previous_gray: GrayImage
    lagged: GrayImage
    """A frame a few back: what changed since it stirs (``ghosts``)."""
    previous_mask: Mask
    difference: GrayImage
    """Out: the frame's difference to the nearer mode."""
    mask: Mask
    """Out: the frame's motion mask."""


class Model(NamedTuple):
    """The background: two modes per pixel and what is known of its variability."""

    background: FloatImage
    """The main mode, in grey levels."""
    alternate: FloatImage
    """The second mode (leaf against sky), background once it recurs (``weight``)."""
    weight: FloatImage
    """0..255: how often the alternate recurs right after a background frame."""
    deviation: FloatImage
    """Grey levels: the pixel's mean |difference| while it is still (its variability)."""


@compiled_helper
def as_model(planes: np.ndarray) -> Model:
    """The model's planes, by name."""
    return Model(planes[0], planes[1], planes[2], planes[3])


# What ``State.kept`` holds for a pixel of a region the ghost step leaves whole (an object
# that stopped, or one on the move with an unchanging inside), and for one first seen
# moving with an unchanging inside (not yet left whole); else 0.
STOPPED = 255
ON_THE_MOVE = 128
SEEN_MOVING = 64


class State(NamedTuple):
    """Per-pixel counts and masks the steps keep (8-bit planes)."""

    settled: np.ndarray
    """Frames each pixel has been still (to 255)."""
    kept: Mask
    """What the ghost step leaves whole: ``STOPPED``, ``ON_THE_MOVE``, ``SEEN_MOVING``."""
    stirring: Mask
    """Pixels that changed since the previous frame or since a few frames back."""
    stirred: np.ndarray
    """Frames left of the ghost step's guard where a pixel stirred lately."""


@compiled_helper
def as_state(planes: np.ndarray) -> State:
    """The state's planes, by name."""
    return State(planes[0], planes[1], planes[2], planes[3])


class Rings(NamedTuple):
    """Scratch rows of the streamed step, ``RING`` of each (row y in row y % ``RING``)."""

    limit: np.ndarray
    """Each pixel's own threshold before its neighbourhood's largest."""
    per_pixel: np.ndarray
    """Each pixel's own threshold: the largest in its 3x3."""
    strong: np.ndarray
    """Pixels above their own threshold."""
    changing: np.ndarray
    """Pixels that changed since the previous frame."""
    rounded: np.ndarray
    """The background rounded to grey levels, as learned (before the ghost step)."""


@compiled_helper
def as_rings(planes: np.ndarray) -> Rings:
    """The rings' planes, by name."""
    return Rings(planes[0], planes[1], planes[2], planes[3], planes[4])


@dataclass
class Memory:
    """Everything the method keeps for frames of one size, allocated at the first."""

    model_planes: np.ndarray
    state_planes: np.ndarray
    ring_planes: np.ndarray
    raw: Mask
    """The last frame's raw motion (difference above the plain threshold)."""
    next_raw: Mask
    """Where this frame's raw motion goes; the two swap after each frame (``advance``)."""
    still_frames: np.ndarray
    """uint16: frames each motion region's pixel has gone without any change."""
    row_gains: FloatImage
    """Each row's gain, as the step last measured it."""
    model: Model = field(init=False)
    state: State = field(init=False)

    def __post_init__(self) -> None:
        self.model = Model(*self.model_planes)
        self.state = State(*self.state_planes)

    @classmethod
    def for_frame(cls, gray: GrayImage, deviation: FloatImage | None = None) -> Memory:
        """``gray`` as both modes, no alternate weight, ``deviation`` (or none); every
        pixel settled, nothing moving, kept or stirring."""
        height, width = gray.shape
        memory = cls(
            np.empty((len(Model._fields), height, width), np.float32),
            np.zeros((len(State._fields), height, width), np.uint8),
            np.empty((len(Rings._fields), RING, width), np.uint8),
            np.zeros(gray.shape, np.uint8),
            np.zeros(gray.shape, np.uint8),
            np.zeros(gray.shape, np.uint16),
            np.ones(height, np.float32),
        )
        model = memory.model
        model.background[...] = gray
        model.alternate[...] = gray
        model.weight[...] = 0.0
        model.deviation[...] = 0.0 if deviation is None else deviation
        memory.state.settled[...] = 255
        return memory

    def advance(self) -> None:
        """This frame's raw motion becomes the last."""
        self.raw, self.next_raw = self.next_raw, self.raw

    def moved_with_the_view(self) -> tuple[np.ndarray, ...]:
        """The counts and masks kept from frame to frame that move with a followed view
        (besides the model): all but what each frame writes afresh."""
        state = self.state
        return (state.settled, state.kept, state.stirred, self.raw, self.still_frames)


class Rates(NamedTuple):
    """How the per-pixel step learns, fixed by the method's settings (float32, as the
    per-pixel arithmetic is), and which of its mechanisms are on."""

    k: np.float32
    """Thresholds per unit of deviation (the noise's and the pixels' own)."""
    weak_fraction: np.float32
    """Of a pixel's own threshold: what counts as moving next to a strong pixel
    (hysteresis; 1 where it is off)."""
    established_weight: np.float32
    """The weight at which the alternate counts as background (past 255: never)."""
    seed_weight: np.float32
    """The weight a new alternate starts with."""
    learning_rate: np.float32
    mode_rate: np.float32
    near_motion_rate: np.float32
    """The deviation rate of still pixels next to motion."""
    moving_rate: np.float32
    """The learning rate of moving pixels: 0 where the update is selective."""
    frame_gain: bool
    """Whether the modes are lit by the frame's brightness ratio (else 1)."""
    banded: bool
    """Whether rows get their own ratio where the rows' ratios spread (bands)."""
    ghost_absorption: bool
    """Whether the ghost step runs."""


class FrameSettings(NamedTuple):
    """What the step goes by for one frame."""

    threshold: np.float32
    level: np.float32
    """The threshold's whole grey levels (a difference above it is raw motion)."""
    noise_deviation: np.float32
    """The camera noise's mean deviation, as estimated before this frame."""
    deviation_rate: np.float32
    margin: int
    """Grey levels by which the ghost step's range of the still neighbours is widened."""
    learning: bool
    """While the scene is learned (the first frames)."""
    near_motion_known: bool
    """Whether anything moved last frame (still pixels near it teach slowly)."""
    reach: int
    """Pixels each way within which the ghost step seeks still neighbours."""
    settle_frames: int
    """Frames a neighbour must have been still to count near stirring pixels."""
    guard_frames: int
    """Frames the ghost step stays guarded where a pixel stirred (0: no guard)."""
    gain_limit: float
    """Grey levels: pixels further from the background do not set the gain."""
    compare_only_above: float
    """Pixels differing past which the frame is only compared (the caller decides)."""
