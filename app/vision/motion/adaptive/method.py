"""Vigil's default method: an adaptive background model that is cheap and hard to fool.

A running-average background (the classic of Motion and of OpenCV's
``accumulateWeighted``) with a mechanism for each known failure, each in a module of
its own and each with a switch in ``AdaptiveConfig``:

* ``learning`` — two modes per pixel, selective update, per-pixel variability;
* ``threshold`` — each pixel's own threshold, hysteresis;
* ``gains`` — the background lit as the frame is (exposure, bands of mains light);
* ``light`` — light switches, relighting what was moving then;
* ``view`` — a knocked, shaking or turning camera followed;
* ``ghosts`` — what was in the first frame and left, eaten from its rim, and the
  guard that keeps camouflaged objects from being eaten likewise;
* ``regions`` — still regions absorbed, objects that stopped kept whole.

The per-pixel work is one compiled call a frame (``step``); this class decides what
the rare frames that change almost everywhere teach (a light switch, a moved view),
and keeps the model and its state (``model``). While the first ``learning_frames``
frames learn the scene, several mechanisms follow rules of their own (the learning
phase): the variability is the plain mean of its samples, ghosts are sought further
and eaten sooner, and much more of the view must change for the camera to be thought
moved. A model may instead start from a scene estimated ahead (``seed``: what offline
analysis scans for, or a live camera's glances before Activate).

The counts of frames that stand for times (``absorb_after``, ``relit_after``,
``check_every``, ``settle_frames``) are given at 25 fps and scaled to the video's
rate, so a person waiting is kept 5 s at 10 fps and at 60 fps alike; the rates and the
frames the scene is learned over count frames, samples of the scene, whatever the rate.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import replace
from typing import TypedDict

import cv2
import numpy as np

from app.vision.motion.adaptive.config import AdaptiveConfig
from app.vision.motion.adaptive.gains import GAIN_INLIERS
from app.vision.motion.adaptive.ghosts import LEARNING_REACH, LEARNING_SETTLE_FRAMES
from app.vision.motion.adaptive.light import lights_changed, objects_in_view, relit
from app.vision.motion.adaptive.model import FrameSettings, Memory, Rates
from app.vision.motion.adaptive.regions import absorb_still_regions
from app.vision.motion.adaptive.step import step
from app.vision.motion.adaptive.threshold import MEAN_ABS_NOISE
from app.vision.motion.adaptive.view import ViewWatch, follow_scene, moved, scene_shift
from app.vision.motion.base import REFERENCE_FPS, MotionMethod, MotionResult, in_frames
from app.vision.scene_background import END_SAMPLES, SceneBackground
from app.vision.types import GrayImage, Mask
from app.vision.view_shift import shifted

CROWDED_SHARE = 0.4
"""The share of the frame moving past which the noise is measured on still pixels only."""

NEAR_MOTION_DEVIATION_SHARE = 0.3
"""The share of ``deviation_rate`` at which still pixels next to motion teach it."""

NEVER_ESTABLISHED = 256.0
"""An alternate weight past the largest (255): the second mode never counts."""


class AdaptiveBackground(MotionMethod):
    name = "adaptive"
    starts_from_scene = True
    judges_whole_view = True
    description = (
        "two-mode selective running average with per-pixel variability, "
        "light-switch and ghost handling (default)"
    )

    def __init__(
        self,
        sensitivity: float | None = None,
        fps: float = REFERENCE_FPS,
        config: AdaptiveConfig | None = None,
    ) -> None:
        super().__init__(sensitivity, fps)
        self.config = config = config or AdaptiveConfig()
        self.noise.k = config.k
        self._rates = tuple(_rates(config))
        """The step's ``Rates``, as the plain tuple it takes."""
        self._learning_frames = config.learning_frames if config.learning_phase else 0
        self._view = ViewWatch(fps)
        self._scale_times(fps)
        self._memory: Memory | None = None
        self._recent: deque[GrayImage] = deque(maxlen=self.check_every)
        """The last ``check_every`` frames, oldest first."""
        self._previous_mask: Mask | None = None
        self._previous_moving = 0
        """Pixels of ``_previous_mask`` that are set."""
        self._frame_index = 0
        self._scene: SceneBackground | None = None
        """A scene to start from (``seed``), until the first frame."""
        self._started_from_scene = False
        """Whether the model started from a scene estimated ahead (``_start_from``), not
        from a first frame."""

    def set_fps(self, fps: float) -> None:
        super().set_fps(fps)
        self._scale_times(fps)
        self._view.set_fps(fps)
        if self._recent.maxlen != self.check_every:
            self._recent = deque(self._recent, maxlen=self.check_every)

    def _scale_times(self, fps: float) -> None:
        config = self.config
        self.absorb_after = in_frames(config.absorb_after, fps)
        self.relit_after = in_frames(config.relit_after, fps)
        self.check_every = in_frames(config.check_every, fps)
        settle = config.settle_frames
        self.settle_frames = min(in_frames(settle, fps), 255) if settle else 0

    def apply(self, gray: GrayImage) -> MotionResult:
        if gray.dtype != np.uint8 or gray.ndim != 2:
            # The compiled steps index by grey level and trust the type they are given.
            raise ValueError(f"needs an 8-bit grey frame, not {gray.dtype} of shape {gray.shape}")
        gray = np.ascontiguousarray(gray)
        if self._memory is None or self._memory.raw.shape != gray.shape:
            scene, self._scene = self._scene, None
            if scene is None or scene.background.shape != gray.shape:
                return self._learn(gray)
            self._start_from(scene)
        self._frame_index += 1
        return self._step(gray, followed=False)

    def seed(self, scene: SceneBackground) -> None:
        if self.config.start_from_scene:
            self._scene = scene

    def _start_from(self, scene: SceneBackground) -> None:
        """Take ``scene`` as the model: its background as both modes, its variability as
        the pixels' own, weighed as ``END_SAMPLES`` frames of learning (it was measured
        over five or ten samples). The frames after go on learning as a scene's first
        frames do (the variability at the plain mean of its samples), so what is in view
        at the first frame is motion, and leaves that sway are known at once and better
        known soon."""
        rounded = np.clip(np.rint(scene.background), 0, 255).astype(np.uint8)
        self._learn(rounded)
        assert self._memory is not None
        model = self._memory.model
        model.background[...] = scene.background
        model.alternate[...] = scene.background
        if self.config.variability:
            model.deviation[...] = scene.variability
        self._frame_index = END_SAMPLES
        self._started_from_scene = True

    def _step(self, gray: GrayImage, followed: bool) -> MotionResult:
        """This frame against the model; ``followed``: the second time, once the model
        has been moved with the view for it (``view.follow_scene``).

        Most frames take one compiled call (``step``): it compares, and where few
        enough pixels differ for neither a light switch nor a moved view to be
        possible, learns. The others are compared only; what they teach is decided
        here first.
        """
        memory, config = self._memory, self.config
        assert memory is not None and self._recent and self._previous_mask is not None
        threshold = float(self.threshold)
        learning = self._frame_index <= self._learning_frames
        # Started from a first frame, what it held leaves ghosts: while the scene is
        # learned, they are what is most likely to be moving without a stir. Started
        # from a scene estimated ahead, what moves is mostly objects, as later on.
        ghosts_expected = learning and not self._started_from_scene
        # Past this share of the frame moving, the noise is measured on still pixels
        # only (the estimate, a median, stays put while up to a fair share moves; a
        # mask holds flicker and a shaking camera's edges, which are noise too).
        crowded = self._previous_moving > CROWDED_SHARE * gray.size
        # Where the noise is not known yet, or this is the frame followed after a
        # knock, the frame is compared only: the noise is seeded from it, or the knock
        # frame teaches it nothing.
        fast = not followed and self.noise.sigma is not None
        # Compared only where the frame may be a light switch or the camera moved: the
        # first changes most of the view, the second much of it, of a sudden.
        switched = config.light_switch_fraction * gray.size if config.light_switch else math.inf
        sudden = (
            self._view.sudden(self._frame_index, learning, gray.size)
            if config.follow_view
            else math.inf
        )
        frame = self._frame_settings(
            threshold,
            learning,
            ghosts_expected,
            compare_only_above=min(switched, sudden) if fast else -1.0,
        )
        outputs = np.empty((2, *gray.shape), np.uint8)
        difference, mask = outputs
        # Stirring: changed since the previous frame, or since ``check_every`` back (or
        # since the scene a model started from, for its first frames): an object creeping
        # a fraction of a pixel a frame stirs and is guarded.
        lagged = gray if ghosts_expected else self._recent[0]
        arguments = (
            gray,
            self._recent[-1],
            lagged,
            self._previous_mask,
            difference,
            mask,
            memory.raw,
            memory.next_raw,
            memory.model_planes,
            memory.state_planes,
            memory.ring_planes,
            memory.row_gains,
            self._rates,
        )
        changed, moving = step(*arguments, tuple(frame), False)
        if moving < 0:
            if self.noise.sigma is None:  # The first frame compared: the noise it shows.
                self.noise.update(difference, gray)
                threshold = float(self.threshold)
                changed = int(np.count_nonzero(difference > math.floor(threshold)))
                frame = frame._replace(**_threshold_settings(threshold, self))
            if changed > switched and lights_changed(
                gray,
                difference,
                threshold,
                memory.model.background,
                self._previous_mask,
                config.light_switch_fraction,
            ):
                self._relearn_after_light_switch(gray, threshold)
                return MotionResult(np.zeros_like(gray), difference, threshold, global_change=True)
            # A sudden change over much of the view that is no light: the camera may
            # have been knocked or be turning (or something big stepped in front of it:
            # motion).
            if not followed and changed > sudden:
                shift = scene_shift(memory.model.background, gray, threshold)
                if shift is not None:
                    self._follow(gray, threshold, *shift)
                    return replace(self._step(gray, followed=True), global_change=True)
                self._view.not_found(self._frame_index)
            _, moving = step(*arguments, tuple(frame), True)
        # After the light-switch test: the change a light switch makes is not noise, and
        # a noise estimate that took it in would raise the threshold past it and hide
        # the switch (and everything else) until it had decayed. Nor is what a move
        # leaves of the scene's edges (the frame, followed, has none of the camera's
        # noise left where the scene is). The estimate learns for the next frame.
        if not followed:
            self.noise.update(difference, gray, self._previous_mask if crowded else None)
        if config.still_regions and self._frame_index % self.check_every == 0:
            absorb_still_regions(
                gray,
                mask,
                memory.state,
                memory.still_frames,
                memory.model.background,
                self.check_every,
                self.absorb_after,
                self.relit_after,
                config.keep_stopped,
                # Not while ghosts of a first frame are expected: joined to the objects
                # they came from, on the move, they would be kept whole too.
                keep_moving=config.keep_plain_movers and not ghosts_expected,
            )
        self._recent.append(gray)
        self._previous_mask = mask
        memory.advance()
        self._view.note(changed)
        self._previous_moving = moving
        return MotionResult(mask, difference, threshold)

    def _frame_settings(
        self, threshold: float, learning: bool, ghosts_expected: bool, compare_only_above: float
    ) -> FrameSettings:
        config = self.config
        if not config.variability:
            deviation_rate = 0.0
        else:
            deviation_rate = 1.0 / self._frame_index if learning else config.deviation_rate
        # The guard lasts a few frames past an object's last stir, so that one that
        # stopped mostly reaches the still-region check with its outline whole (which
        # then keeps it whole); longer, and a ghost joined to the object it came from is
        # eaten late. Not while ghosts of a first frame are expected: what stirs then is
        # mostly the objects they came from.
        guard_frames = 1 if ghosts_expected else min(self.check_every // 2 + 1, 255)
        return FrameSettings(
            **_threshold_settings(threshold, self),
            deviation_rate=np.float32(deviation_rate),
            learning=learning,
            near_motion_known=config.near_motion_teaching and self._previous_moving > 0,
            # The ghost step: while the scene is learned, the still neighbours are sought
            # past the deaf rim a start-up ghost has, and settle sooner. So too from a
            # scene estimated ahead: where it kept the wrong end, it has ghosts of its own
            # (with reach 1 then, CDnet fall's F fell below that of no scan at all).
            reach=LEARNING_REACH if learning else 1,
            settle_frames=LEARNING_SETTLE_FRAMES if learning else self.settle_frames,
            guard_frames=guard_frames if config.stirring_guard else 0,
            gain_limit=GAIN_INLIERS * threshold,
            compare_only_above=compare_only_above,
        )

    def _learn(self, gray: GrayImage) -> MotionResult:
        """Take this frame as the background (first frame, or after a light switch).

        The variability is kept: which pixels sway is a property of the
        scene, not of its lighting.
        """
        old = self._memory
        kept = old is not None and old.raw.shape == gray.shape
        self._memory = Memory.for_frame(
            gray, old.model.deviation if old is not None and kept else None
        )
        self._view.reset()
        self._recent = deque([gray], maxlen=self.check_every)
        self._previous_mask = np.zeros_like(gray)
        self._previous_moving = 0
        return MotionResult(self._previous_mask, self._previous_mask, self.threshold)

    def _relearn_after_light_switch(self, gray: GrayImage, threshold: float) -> None:
        """Take this frame as the background, except where something was moving.

        An object in view when the light changes would otherwise become
        background: lost until it moved off its own picture, which then stayed
        behind as a ghost. Where the last mask was (``light.objects_in_view``), the
        background is the old one mapped to the new light (``light.relit``), and
        that stays the last mask, so a second switch in a row keeps it too.
        """
        assert self._memory is not None and self._previous_mask is not None
        old_background, moving = self._memory.model.background, self._previous_mask
        anything_moved = self._previous_moving > 0
        self._learn(gray)
        if not (anything_moved and self.config.relight_objects):
            return
        kept = objects_in_view(moving, self.config.light_switch_fraction)
        if kept is None:
            return
        where = kept != 0
        # Not the last mask's still pixels: the object has stepped onto some of them.
        mapped = relit(old_background, gray, ~where, threshold**2)
        assert self._memory is not None
        model = self._memory.model
        model.background[where] = mapped[where]
        model.alternate[...] = model.background
        self._memory.state.settled[where] = 0
        self._previous_mask = kept
        self._previous_moving = cv2.countNonZero(kept)

    def _follow(self, gray: GrayImage, threshold: float, dx: float, dy: float) -> None:
        """Move the model, its state and the frames kept (dx, dy) pixels with the view,
        which may still be moving on the next frames."""
        assert self._memory is not None and self._previous_mask is not None
        memory = self._memory
        follow_scene(memory.model, memory.moved_with_the_view(), gray, threshold, dx, dy)
        self._recent = deque(
            (shifted(seen, dx, dy, gray.copy()) for seen in self._recent),
            maxlen=self.check_every,
        )
        self._previous_mask = moved(self._previous_mask, dx, dy, smooth=False)
        self._previous_moving = cv2.countNonZero(self._previous_mask)
        self._view.followed(self._frame_index)

    def reset(self) -> None:
        super().reset()
        self._memory = None
        self._recent.clear()
        self._previous_mask = None
        self._previous_moving = 0
        self._frame_index = 0
        self._scene = None
        self._started_from_scene = False


def _rates(config: AdaptiveConfig) -> Rates:
    """The step's rates and switches for ``config`` (float32, as the step computes)."""
    return Rates(
        k=np.float32(config.k),
        weak_fraction=np.float32(config.weak_fraction if config.hysteresis else 1.0),
        established_weight=np.float32(
            255.0 * config.mode_weight if config.second_mode else NEVER_ESTABLISHED
        ),
        seed_weight=np.float32(255.0 * config.mode_rate),
        learning_rate=np.float32(config.learning_rate),
        mode_rate=np.float32(config.mode_rate),
        near_motion_rate=np.float32(
            NEAR_MOTION_DEVIATION_SHARE * config.deviation_rate if config.variability else 0.0
        ),
        moving_rate=np.float32(0.0 if config.selective_update else config.learning_rate),
        frame_gain=config.frame_gain,
        banded=config.row_gains,
        ghost_absorption=config.ghost_absorption,
    )


class _ThresholdSettings(TypedDict):
    threshold: np.float32
    level: np.float32
    noise_deviation: np.float32
    margin: int


def _threshold_settings(threshold: float, method: AdaptiveBackground) -> _ThresholdSettings:
    """The frame settings that follow from its threshold and the noise: the noise as the
    estimate was when the frame was thresholded (it learns from the frame for the next),
    and the ghost step's margin."""
    return _ThresholdSettings(
        threshold=np.float32(threshold),
        level=np.float32(math.floor(threshold)),
        noise_deviation=np.float32(MEAN_ABS_NOISE * (method.noise.sigma or 0.0)),
        margin=round(threshold * method.config.weak_fraction),
    )


def warm_up() -> None:
    """Compile the model's kernels (the first run on a machine) or load them from the
    cache now, rather than on a camera's first activated frame: a square that moves,
    then stops and is absorbed, takes every step once."""
    method = AdaptiveBackground(config=AdaptiveConfig(check_every=2, absorb_after=2, relit_after=2))
    for index in range(8):
        frame = np.full((24, 32), 60, np.uint8)
        left = min(index, 4) * 4
        frame[8:16, left : left + 8] = 200
        method.apply(frame)
