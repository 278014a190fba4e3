"""Vigil's default: an adaptive background model that is cheap and hard to fool.

A running-average background (the classic of Motion and of OpenCV's
``accumulateWeighted``) with these additions, each aimed at a known failure:

* **Selective update** — pixels that move do not teach the background, so a
  slow, uniform object is not absorbed while it crosses (frame difference's
  weak spot).
* **Gain compensation and light-switch handling** — the background is scaled
  to the frame's brightness each frame (auto-exposure, clouds), the ratio
  taken over pixels that were still and still look like the background, and
  row by row where the rows' ratios spread across the frame (mains light read
  by a rolling shutter lights the rows in bands that drift each frame); a
  change that covers most of the scene, where nothing moved before too, and
  is brighter (or darker) almost everywhere is re-learned at once instead of
  reported (a lorry filling the view differs only where it drove in; a camera
  that shook differs as widely, but both ways at each edge). Where something
  was moving then, the old background is kept, relit by a line fitted locally
  from the old background to the new frame, so an object in view stays an
  object. The noise estimate learns only from frames that were no light
  switch, and from still pixels only when much of the frame moves.
* **A camera that is knocked** — where much of the view turns "moving" at
  once and is no light switch, the shift of the scene in the picture is
  sought (template matching of the frame's middle against the background);
  if the background moved by it explains the change, the whole model moves
  with the scene and the frame is compared again, so what moves in it is
  still found and the scene is not reported as motion. A shaking camera is
  followed frame by frame, and one that turns (a pan) every few frames: the
  change is sudden against the calm of the last half second, and once the view
  has been followed, a little change is enough to seek it again. A very slow
  pan, a turn about the lens axis or a zoom is not followed (stale-region
  absorption handles them), nor is a shift that
  shows in too few parts of the view to tell (``view_shift``): on a plain wall,
  an object's own move explains the change as well as a moved view would.
* **A second background mode** — each pixel keeps an alternate value beside
  its main one (a cheap two-mode mixture, after Stauffer and Grimson, 1999):
  leaf against sky, an edge that a shaking camera moves back and forth. The
  alternate counts as background once it *recurs*: its weight grows only on
  frames that match it right after a background frame, so a stopped object,
  which stays foreground, never earns one (still-region absorption handles
  it instead). A value far from both modes takes the place of a weak
  alternate, but gets a fresh weight only right after a background frame too:
  a passing object's inside, replacing it frame after frame, leaves it to
  fade.
* **Per-pixel variability** — each pixel keeps its mean deviation from the
  background, learned from background frames and from frames where its
  detection flips (the blink of SuBSENSE, St-Charles et al., 2015), clipped
  at its own threshold so one passing object cannot inflate it. Deviation
  beyond what the camera noise explains, taken as the largest in a pixel's
  3x3 neighbourhood, raises that pixel's threshold by the same ``k`` that
  scales the noise: leaves and water get deaf, still pixels keep the plain
  threshold. For the first ``learning_frames`` frames the deviation is the
  plain, unclipped mean of those samples, so a sway is known after one
  swing; flips deep inside a solid changed region (an object stepping in,
  a ghost uncovered) do not count then. Afterwards, still pixels right next
  to motion teach it at a fraction of the rate: they may be the parts of a
  camouflaged object that match the background, and a slow one would
  otherwise teach its own pixels deaf, then vanish piece by piece.
* **Hysteresis** — weaker pixels next to strong ones count too, so
  low-contrast objects come out whole.
* **Ghost absorption** — moving pixels that do not change from frame to
  frame and match the background of their still neighbours are absorbed at
  once, eating a ghost (something that was in the first frame and left) from
  its rim inwards (while the scene is being learned, the neighbours are
  sought three pixels away, past the deaf rim a start-up ghost has). Inside
  an object on the move, and for a few frames after it stops (so that the
  stale-region check below mostly sees it whole), only neighbours that have
  been still for a while count, so a camouflaged object is not eaten from the
  one point where it matches the background; and a region that moves with most
  of its inside unchanged (a lorry's plain side, something creeping), seen so at
  two stale-region checks running, is left whole. A region that stays "moving"
  without any change, from frame to frame or over ``check_every`` frames (a
  ghost or a stopped object, not one creeping a fraction of a pixel a frame), becomes
  background after ``relit_after`` frames where it is no object: the frame
  there is the background in another light (it correlates with it: a lamp came
  on, a shadow fell), or a ghost (across the region's border the frame steps
  less than the background does). An object that stopped (a person waiting)
  stays for ``absorb_after`` frames (5 s at 25 fps), kept whole, out of the
  ghost step's reach, where its outline is clearly an object's, and stays kept
  (until ``absorb_after``) while it stays still.

The counts of frames that stand for times (``absorb_after``, ``relit_after``,
``check_every``, ``settle_frames``) are given at 25 fps and scaled to the
video's rate, so a person waiting is kept 5 s at 10 fps and at 60 fps alike;
the rates and the frames the scene is learned over count frames, samples of
the scene, whatever the rate.

The per-pixel work is compiled (``adaptive_kernels``): most frames take one
call, neighbourhood steps included; this class decides what the rare frames
that change almost everywhere teach, and keeps the model and its state in a few
stacked planes, reused from frame to frame (fresh large buffers cost page
faults). The regions of the stale-region check are OpenCV's.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import replace

import cv2
import numpy as np

from app.vision.mask_box import motion_box
from app.vision.motion import adaptive_kernels as kernels
from app.vision.motion.adaptive_kernels import GUARD_REACH, LEARNING_REACH
from app.vision.motion.base import REFERENCE_FPS, MotionMethod, MotionResult, in_frames
from app.vision.scene_background import END_SAMPLES, SceneBackground
from app.vision.types import FloatImage, GrayImage, Mask
from app.vision.view_shift import VIEW_SHIFT_REACH, shift_explains, shifted

MEAN_ABS_NOISE = math.sqrt(2.0 / math.pi)
"""E|X| / sigma for Gaussian X: the mean deviation that camera noise alone gives."""

GAIN_INLIERS = 3.0
"""Pixels further than this many thresholds from the background do not set the gain."""

GAIN_GRID = 4
"""The gain is measured on every GAIN_GRID-th row and column."""

LEARNING_SETTLE_FRAMES = 5
"""``settle_frames`` while the scene is being learned: ghosts of what was in the first
frame are expected then, and are eaten sooner."""

LIGHT_SPREAD = 16.0
"""Pixels: the standard deviation of the Gaussian window over which a light change is
fitted. A lamp's light changes over tens of pixels, and a window this wide reaches the
still pixels around an object some sixty pixels across."""

LIGHT_WINDOW_LEAST = 0.05
"""The least (weighted) share of still pixels a window needs for its own fit."""

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

CROWDED_SHARE = 0.4
"""The share of the frame moving past which the noise is measured on still pixels only."""

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

NEAR_MOTION_DEVIATION_SHARE = 0.3
"""The share of ``deviation_rate`` at which still pixels next to motion teach it."""


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
        k: float = 3.5,
        learning_rate: float = 0.03,
        light_switch_fraction: float = 0.5,
        mode_rate: float = 0.04,
        mode_weight: float = 0.06,
        deviation_rate: float = 0.1,
        weak_fraction: float = 0.5,
        absorb_after: int = 125,
        relit_after: int = 30,
        check_every: int = 6,
        learning_frames: int = 20,
        settle_frames: int = 10,
        fps: float = REFERENCE_FPS,
    ) -> None:
        super().__init__(sensitivity, fps)
        # 3.5 sigma, not the usual 4: the per-pixel variability, not a higher
        # global threshold, is what keeps swaying pixels quiet here.
        self.noise.k = k
        self.learning_rate = learning_rate
        self.light_switch_fraction = light_switch_fraction
        # A new alternate seen right after a background frame starts at mode_rate,
        # below mode_weight, so it takes a second sighting to count: with the
        # defaults, within 17 frames.
        self.mode_rate = mode_rate
        self.mode_weight = mode_weight
        self.deviation_rate = deviation_rate
        self.weak_fraction = weak_fraction
        self.learning_frames = learning_frames
        if not 0 <= settle_frames <= 255:
            raise ValueError(f"settle_frames counts to 255 at most, not {settle_frames}")
        self._times_in_frames = (absorb_after, relit_after, check_every, settle_frames)
        """The counts that stand for times, at ``REFERENCE_FPS``."""
        self._scale_times(fps)
        guard = 2 * GUARD_REACH + 1
        self._guard_kernel = np.ones((guard, guard), np.uint8)
        self._model: np.ndarray | None = None
        """Background, alternate, weight (0..255: how often the alternate recurs) and
        deviation (grey levels: mean |difference| when still), float32 planes
        (``kernels.MODEL``)."""
        self._state: np.ndarray | None = None
        """Settled, kept, stirring, the two raw planes and the guard's frames left
        (``kernels.STATE``)."""
        self._raw_plane = kernels.RAW[0]
        """The state's plane that holds the previous frame's raw motion."""
        self._calm: deque[int] = deque(maxlen=self.calm_frames)
        """Pixels of raw motion in each of the last ``calm_frames`` frames."""
        self._next_search = 0
        """The first frame on which a moved view may be sought again (``search_backoff``)."""
        self._following_until = 0
        """The frame until which the view may still be moving (``FOLLOWING_SHARE``)."""
        self._rings: np.ndarray | None = None
        self._gains: np.ndarray | None = None
        self._recent: deque[GrayImage] = deque(maxlen=self.check_every)
        """The last ``check_every`` frames, oldest first."""
        self._previous_mask: Mask | None = None
        self._previous_moving = 0
        """Pixels of ``_previous_mask`` that are set."""
        self._still_frames: np.ndarray | None = None
        self._frame_index = 0
        self._scene: SceneBackground | None = None
        """A scene to start from (``seed``), until the first frame."""
        self._started_from_scene = False
        """Whether the model started from a scene estimated ahead (``_start_from``), not
        from a first frame."""

    def set_fps(self, fps: float) -> None:
        super().set_fps(fps)
        self._scale_times(fps)
        if self._recent.maxlen != self.check_every:
            self._recent = deque(self._recent, maxlen=self.check_every)
        if self._calm.maxlen != self.calm_frames:
            self._calm = deque(self._calm, maxlen=self.calm_frames)

    def _scale_times(self, fps: float) -> None:
        absorb_after, relit_after, check_every, settle_frames = self._times_in_frames
        self.absorb_after = in_frames(absorb_after, fps)
        self.relit_after = in_frames(relit_after, fps)
        self.check_every = in_frames(check_every, fps)
        self.settle_frames = min(in_frames(settle_frames, fps), 255) if settle_frames else 0
        self.calm_frames = in_frames(CALM_FRAMES, fps)
        self.search_backoff = in_frames(SEARCH_BACKOFF, fps)

    # The model's planes that the steps in Python work on.

    @property
    def _background(self) -> FloatImage:
        assert self._model is not None
        return self._model[kernels.BACKGROUND]

    @property
    def _alternate(self) -> FloatImage:
        assert self._model is not None
        return self._model[kernels.ALTERNATE]

    def apply(self, gray: GrayImage) -> MotionResult:
        if gray.dtype != np.uint8 or gray.ndim != 2:
            # The compiled steps index by grey level and trust the type they are given.
            raise ValueError(f"needs an 8-bit grey frame, not {gray.dtype} of shape {gray.shape}")
        gray = np.ascontiguousarray(gray)
        if self._model is None or self._model.shape[1:] != gray.shape:
            scene, self._scene = self._scene, None
            if scene is None or scene.background.shape != gray.shape:
                return self._learn(gray)
            self._start_from(scene)
        self._frame_index += 1
        return self._step(gray, followed=False)

    def seed(self, scene: SceneBackground) -> None:
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
        assert self._model is not None
        self._model[kernels.BACKGROUND] = scene.background
        self._model[kernels.ALTERNATE] = scene.background
        self._model[kernels.DEVIATION] = scene.variability
        self._frame_index = END_SAMPLES
        self._started_from_scene = True

    def _step(self, gray: GrayImage, followed: bool) -> MotionResult:
        """This frame against the model; ``followed``: the second time, once the model
        has been moved with the view for it (``_follow_scene``).

        Most frames take one compiled call (``kernels.step``): it compares, and
        where few enough pixels differ for neither a light switch nor a knock to be
        possible, learns. The others are compared only; what they teach is decided
        here first.
        """
        assert self._model is not None and self._state is not None
        assert self._rings is not None and self._gains is not None and self._recent
        assert self._previous_mask is not None
        threshold = float(self.threshold)
        learning = self._frame_index <= self.learning_frames
        # Started from a first frame, what it held leaves ghosts: while the scene is
        # learned, they are what is most likely to be moving without a stir. Started
        # from a scene estimated ahead, what moves is mostly objects, as later on.
        ghosts_expected = learning and not self._started_from_scene
        raw_plane = kernels.RAW[0] + kernels.RAW[1] - self._raw_plane
        # Past this share of the frame moving, the noise is measured on still pixels
        # only (the estimate, a median, stays put while up to a fair share moves; a
        # mask holds flicker and a shaking camera's edges, which are noise too).
        crowded = self._previous_moving > CROWDED_SHARE * gray.size
        # Where the noise is not known yet, or this is the frame followed after a
        # knock, the frame is compared only: the noise is seeded from it, or the knock
        # frame teaches it nothing.
        fast = not followed and self.noise.sigma is not None
        rates = self._rates(learning)
        settings = np.empty(kernels.SETTINGS, np.int64)
        settings[kernels.LEARN_ONLY] = False  # Compare first.
        settings[kernels.LEARNING] = learning
        settings[kernels.NEAR_MOTION_KNOWN] = self._previous_moving > 0
        # The ghost step: while the scene is learned, the still neighbours are sought
        # past the deaf rim a start-up ghost has, and settle sooner. So too from a scene
        # estimated ahead: where it kept the wrong end, it has ghosts of its own (with
        # reach 1 then, CDnet fall's F fell below that of no scan at all).
        settings[kernels.REACH] = LEARNING_REACH if learning else 1
        settings[kernels.SETTLE_FRAMES] = LEARNING_SETTLE_FRAMES if learning else self.settle_frames
        settings[kernels.RAW_PLANE] = raw_plane
        settings[kernels.GAIN_STEP] = GAIN_GRID
        # The guard lasts a few frames past an object's last stir, so that one that
        # stopped mostly reaches the stale-region check with its outline whole (which
        # then keeps it whole); longer, and a ghost joined to the object it came from is
        # eaten late. Not while ghosts of a first frame are expected: what stirs then is
        # mostly the objects they came from.
        guard_frames = 1 if ghosts_expected else min(self.check_every // 2 + 1, 255)
        settings[kernels.GUARD_FRAMES] = guard_frames
        self._set_threshold(threshold, rates, settings)
        bounds = np.empty(kernels.BOUNDS)
        bounds[kernels.GAIN_LIMIT] = GAIN_INLIERS * threshold
        # Compared only where the frame may be a light switch or the camera moved: the
        # first changes most of the view, the second much of it, of a sudden.
        share = LEARNING_CAMERA_MOVE_SHARE if learning else CAMERA_MOVE_SHARE
        if self._frame_index < self._next_search:
            sudden = math.inf  # A search just found the view where it was.
        elif self._frame_index < self._following_until and not learning:
            sudden = FOLLOWING_SHARE * gray.size
        else:
            sudden = max(share * gray.size, SUDDEN_GROWTH * min(self._calm, default=0))
        bounds[kernels.COMPARE_ONLY_ABOVE] = (
            min(self.light_switch_fraction * gray.size, sudden) if fast else -1.0
        )
        outputs = np.empty((kernels.OUTPUTS, *gray.shape), np.uint8)
        difference, mask = outputs[kernels.DIFFERENCE], outputs[kernels.MASK]
        # Stirring: changed since the previous frame, or since ``check_every`` back (or
        # since the scene a model started from, for its first frames): an object creeping
        # a fraction of a pixel a frame stirs and is guarded.
        lagged = gray if ghosts_expected else self._recent[0]
        arguments = (
            gray,
            self._recent[-1],
            lagged,
            self._previous_mask,
            self._model,
            self._state,
            self._rings,
            self._gains,
            outputs,
            rates,
            settings,
            bounds,
        )
        changed, _, moving = kernels.step(*arguments)
        if moving < 0:
            if self.noise.sigma is None:  # The first frame compared: the noise it shows.
                self.noise.update(difference, gray)
                threshold = float(self.threshold)
                changed = int(np.count_nonzero(difference > math.floor(threshold)))
                self._set_threshold(threshold, rates, settings)
            if changed > self.light_switch_fraction * gray.size and self._lights_changed(
                gray, difference, threshold
            ):
                self._relearn_after_light_switch(gray, threshold)
                return MotionResult(np.zeros_like(gray), difference, threshold, global_change=True)
            # A sudden change over much of the view that is no light: the camera may
            # have been knocked or be turning (or something big stepped in front of it:
            # motion).
            if not followed and changed > sudden:
                shift = self._scene_shift(gray, threshold)
                if shift is not None:
                    self._follow_scene(gray, threshold, *shift)
                    # The frames after this one.
                    self._following_until = self._frame_index + 1 + self.calm_frames
                    return replace(self._step(gray, followed=True), global_change=True)
                if self._frame_index >= self._following_until:
                    # Not while following: a view that moved less than a step since is
                    # sought again on the next frame.
                    self._next_search = self._frame_index + 1 + self.search_backoff
            settings[kernels.LEARN_ONLY] = True
            _, _, moving = kernels.step(*arguments)
        # After the light-switch test: the change a light switch makes is not noise, and
        # a noise estimate that took it in would raise the threshold past it and hide
        # the switch (and everything else) until it had decayed. Nor is what a move
        # leaves of the scene's edges (the frame, followed, has none of the camera's
        # noise left where the scene is). The estimate learns for the next frame.
        if not followed:
            self.noise.update(difference, gray, self._previous_mask if crowded else None)
        if self._frame_index % self.check_every == 0:
            # Not while ghosts of a first frame are expected: joined to the objects they
            # came from, on the move, they would be kept whole too.
            self._absorb_still_regions(gray, mask, keep_moving=not ghosts_expected)
        self._recent.append(gray)
        self._previous_mask = mask
        self._raw_plane = raw_plane
        self._calm.append(changed)
        self._previous_moving = moving
        return MotionResult(mask, difference, threshold)

    def _rates(self, learning: bool) -> np.ndarray:
        """A frame's float32 settings (``kernels.RATES``) but those of its threshold
        (``_set_threshold``); ``kernels.step`` sets the gain."""
        rates = np.empty(kernels.RATES, np.float32)
        rates[kernels.K] = self.noise.k
        rates[kernels.WEAK_FRACTION] = self.weak_fraction
        rates[kernels.ESTABLISHED_WEIGHT] = 255.0 * self.mode_weight
        rates[kernels.SEED_WEIGHT] = 255.0 * self.mode_rate
        rates[kernels.LEARNING_RATE] = self.learning_rate
        rates[kernels.MODE_RATE] = self.mode_rate
        rates[kernels.DEVIATION_RATE] = 1.0 / self._frame_index if learning else self.deviation_rate
        rates[kernels.NEAR_MOTION_RATE] = NEAR_MOTION_DEVIATION_SHARE * self.deviation_rate
        return rates

    def _set_threshold(self, threshold: float, rates: np.ndarray, settings: np.ndarray) -> None:
        """The settings that follow from the frame's threshold and noise: the noise as the
        estimate was when the frame was thresholded (it learns from the frame for the
        next), and the ghost step's margin."""
        rates[kernels.THRESHOLD] = threshold
        rates[kernels.LEVEL] = math.floor(threshold)
        rates[kernels.NOISE_DEVIATION] = MEAN_ABS_NOISE * (self.noise.sigma or 0.0)
        settings[kernels.MARGIN] = round(threshold * self.weak_fraction)

    def _learn(self, gray: GrayImage) -> MotionResult:
        """Take this frame as the background (first frame, or after a light switch).

        The variability is kept: which pixels sway is a property of the
        scene, not of its lighting.
        """
        deviation = None if self._model is None else self._model[kernels.DEVIATION]
        self._model = np.empty((kernels.MODEL, *gray.shape), np.float32)
        self._model[kernels.BACKGROUND] = gray
        self._model[kernels.ALTERNATE] = gray
        self._model[kernels.WEIGHT] = 0.0
        keep = deviation is not None and deviation.shape == gray.shape
        self._model[kernels.DEVIATION] = deviation if keep else 0.0
        self._state = np.zeros((kernels.STATE, *gray.shape), np.uint8)
        self._state[kernels.SETTLED] = 255
        self._raw_plane = kernels.RAW[1]
        self._calm.clear()
        self._next_search = self._following_until = 0
        self._rings = kernels.ring_rows(gray.shape[1])
        self._gains = kernels.row_gains(gray.shape[0])
        self._still_frames = np.zeros(gray.shape, np.uint16)
        self._recent = deque([gray], maxlen=self.check_every)
        self._previous_mask = np.zeros_like(gray)
        self._previous_moving = 0
        return MotionResult(self._previous_mask, self._previous_mask, self.threshold)

    def _lights_changed(self, gray: GrayImage, difference: GrayImage, threshold: float) -> bool:
        """Whether a frame that differs from the background almost everywhere does so
        because the light changed (or the exposure jumped): it differs where nothing
        moved last frame too, by more than ``threshold`` and the same way at most of
        those pixels (the median change). An object that fills the view differs only
        where it is, grown from where it was; a camera that shook differs everywhere,
        but brighter on one side of each edge and darker on the other."""
        assert self._previous_mask is not None
        grid = (slice(None, None, GAIN_GRID), slice(None, None, GAIN_GRID))
        was_still = self._previous_mask[grid] == 0
        if was_still.any():
            raw = difference[grid][was_still] > math.floor(threshold)
            changed = np.count_nonzero(raw) / np.count_nonzero(was_still)
            if changed <= self.light_switch_fraction:
                return False
        shift = np.median(gray[grid].astype(np.float32) - self._background[grid])
        return bool(abs(shift) > threshold)

    def _relearn_after_light_switch(self, gray: GrayImage, threshold: float) -> None:
        """Take this frame as the background, except where something was moving.

        An object in view when the light changes would otherwise become
        background: lost until it moved off its own picture, which then stayed
        behind as a ghost. Where the last mask was (widened by ``GUARD_REACH``
        for the step the object took since), the background is the old one
        mapped to the new light (``relit``), and that stays the last mask, so a
        second switch in a row keeps it too. Where that would cover as much of
        the frame as a light switch does, the "motion" was the light coming on
        over a few frames, not objects: the frame is all taken.
        """
        assert self._previous_mask is not None
        old_background, moving, anything_moved = (
            self._background,  # The old model's: learning makes a new one.
            self._previous_mask,
            self._previous_moving > 0,
        )
        self._learn(gray)
        if not anything_moved:
            return
        kept = cv2.dilate(moving, self._guard_kernel)
        kept_pixels = cv2.countNonZero(kept)
        if kept_pixels > self.light_switch_fraction * kept.size:
            return
        where = kept != 0
        # Not the last mask's still pixels: the object has stepped onto some of them.
        mapped = relit(old_background, gray, ~where, threshold**2)
        self._background[where] = mapped[where]
        self._alternate[...] = self._background
        assert self._state is not None
        self._state[kernels.SETTLED][where] = 0
        self._previous_mask = kept
        self._previous_moving = kept_pixels

    def _scene_shift(self, gray: GrayImage, threshold: float) -> tuple[float, float] | None:
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
        background = cv2.resize(self._background, size, interpolation=cv2.INTER_AREA)
        picture = cv2.resize(frame, size, interpolation=cv2.INTER_AREA)
        reach = max(2, round(VIEW_SHIFT_REACH * size[0]))
        if min(size) <= 4 * reach:
            return None
        dx, dy = (reduce * shift for shift in _matched_shift(background, picture, reach))
        if math.hypot(dx, dy) < CAMERA_MOVE_LEAST:
            return None
        # Checked on a grid, as the gain is measured.
        explained = shift_explains(self._background, frame, dx, dy, threshold, GAIN_GRID)
        return (dx, dy) if explained else None

    def _follow_scene(self, gray: GrayImage, threshold: float, dx: float, dy: float) -> None:
        """Move the whole model (dx, dy) pixels with the scene, so that only what moves
        in it is motion. The strip that came into view takes this frame as its
        background, with nothing learned about it yet (no alternate, no variability,
        not settled, never still). Where the moved background explains the frame, the
        frame is taken as the background: it is the sharper picture of the scene
        (resampling blurs, and a camera knocked again and again would blur the
        background until its edges were motion)."""
        assert self._model is not None and self._state is not None
        assert self._previous_mask is not None and self._still_frames is not None
        frame = gray.astype(np.float32)

        def moved(image: np.ndarray, smooth: bool = True) -> np.ndarray:
            return shifted(image, dx, dy, np.zeros_like(image), smooth)

        background = shifted(self._background, dx, dy, frame.copy())
        explained = np.abs(frame - background) <= threshold
        background[explained] = frame[explained]
        model = self._model
        model[kernels.BACKGROUND] = background
        model[kernels.ALTERNATE] = shifted(self._alternate, dx, dy, frame.copy())
        for plane in (kernels.WEIGHT, kernels.DEVIATION):
            model[plane] = moved(model[plane])
        self._recent = deque(
            (shifted(seen, dx, dy, gray.copy()) for seen in self._recent),
            maxlen=self.check_every,
        )
        self._previous_mask = moved(self._previous_mask, smooth=False)
        self._previous_moving = cv2.countNonZero(self._previous_mask)
        for plane in (kernels.SETTLED, kernels.KEPT, kernels.STIRRED, self._raw_plane):
            self._state[plane] = moved(self._state[plane], smooth=False)
        self._still_frames = moved(self._still_frames, smooth=False)

    def _absorb_still_regions(self, gray: GrayImage, mask: Mask, keep_moving: bool) -> None:
        """Count, per motion region, frames without any change; absorb the stale ones;
        with ``keep_moving``, keep whole those on the move with an unchanging inside."""
        assert self._still_frames is not None and self._state is not None
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
        kernels.age_still_regions(
            labels,
            rows.start,
            cols.start,
            regions,
            self._state[kernels.STIRRING],
            gray,
            self.check_every,
            self.absorb_after,
            self.relit_after,
            RELIT_CORRELATION,
            LEAST_PATTERN,
            CLEAR_EDGE,
            keep_moving,
            self._still_frames,
            self._background,
            self._state[kernels.KEPT],
        )

    def reset(self) -> None:
        super().reset()
        self._model = None
        self._state = None
        self._rings = None
        self._gains = None
        self._recent.clear()
        self._previous_mask = None
        self._previous_moving = 0
        self._still_frames = None
        self._frame_index = 0
        self._scene = None
        self._started_from_scene = False


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


def warm_up() -> None:
    """Compile the model's kernels (the first run on a machine) or load them from the
    cache now, rather than on a camera's first activated frame: a square that moves,
    then stops and is absorbed, takes every step once."""
    method = AdaptiveBackground(check_every=2, absorb_after=2, relit_after=2)
    for step in range(8):
        frame = np.full((24, 32), 60, np.uint8)
        left = min(step, 4) * 4
        frame[8:16, left : left + 8] = 200
        method.apply(frame)
