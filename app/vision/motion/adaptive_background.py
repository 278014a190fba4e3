"""Vigil's default: an adaptive background model that is cheap and hard to fool.

A running-average background (the classic of Motion and of OpenCV's
``accumulateWeighted``) with these additions, each aimed at a known failure:

* **Selective update** — pixels that move do not teach the background, so a
  slow, uniform object is not absorbed while it crosses (frame difference's
  weak spot).
* **Gain compensation and light-switch handling** — the background is scaled
  to the frame's brightness each frame (auto-exposure, clouds), the ratio
  taken over pixels that were still and still look like the background; a
  change that covers most of the scene is re-learned at once instead of
  reported.
* **A second background mode** — each pixel keeps an alternate value beside
  its main one (a cheap two-mode mixture, after Stauffer and Grimson, 1999):
  leaf against sky, an edge that a shaking camera moves back and forth. The
  alternate counts as background once it *recurs*: its weight grows only on
  frames that match it right after a background frame, so a stopped object,
  which stays foreground, never earns one (still-region absorption handles
  it instead).
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
  a ghost uncovered) do not count then.
* **Hysteresis** — weaker pixels next to strong ones count too, so
  low-contrast objects come out whole.
* **Ghost absorption** — moving pixels that do not change from frame to
  frame and match the background of their still neighbours are absorbed at
  once, eating a ghost (something that was in the first frame and left) from
  its rim inwards (while the scene is being learned, the neighbours are
  sought three pixels away, past the deaf rim a start-up ghost has); a
  region that stays "moving" without any change between consecutive frames
  (a ghost or a stopped object) becomes background after ``absorb_after``
  frames.

Per-frame work is done on 8-bit images wherever a grey level is precise
enough (masks are 0 or 255, so "a and not b" is one saturating subtraction);
the float models are only read and accumulated into, so a frame allocates no
new full-size float image (fresh large buffers cost page faults).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from app.vision.motion.base import MotionMethod, MotionResult, threshold_difference
from app.vision.types import FloatImage, GrayImage, Mask

MEAN_ABS_NOISE = math.sqrt(2.0 / math.pi)
"""E|X| / sigma for Gaussian X: the mean deviation that camera noise alone gives."""

GAIN_INLIERS = 3.0
"""Pixels further than this many thresholds from the background do not set the gain."""

GAIN_GRID = 4
"""The gain is measured on every GAIN_GRID-th row and column."""


def _scalar(value: float) -> np.ndarray:
    """A number as OpenCV's arithmetic takes it (its stubs allow no bare float)."""
    return np.array([value])


class AdaptiveBackground(MotionMethod):
    name = "adaptive"
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
        absorb_after: int = 30,
        check_every: int = 6,
        learning_frames: int = 20,
    ) -> None:
        super().__init__(sensitivity)
        # 3.5 sigma, not the usual 4: the per-pixel variability, not a higher
        # global threshold, is what keeps swaying pixels quiet here.
        self.noise.k = k
        self.learning_rate = learning_rate
        self.light_switch_fraction = light_switch_fraction
        # A new alternate starts at mode_rate, below mode_weight, so it takes
        # a second sighting to count: with the defaults, within 17 frames.
        self.mode_rate = mode_rate
        self.mode_weight = mode_weight
        self.deviation_rate = deviation_rate
        self.weak_fraction = weak_fraction
        self.absorb_after = absorb_after
        self.check_every = check_every
        self.learning_frames = learning_frames
        self._grow_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))
        self._neighbour_kernel = np.ones((3, 3), np.uint8)
        # Three pixels each way: how deep "inside" a region is, and how far a
        # ghost's rim reaches, while the scene is being learned.
        self._learning_kernel = np.ones((7, 7), np.uint8)
        self._background: FloatImage | None = None
        self._alternate: FloatImage | None = None
        self._weight: FloatImage | None = None  # 0..255: how often the alternate recurs
        self._seed_weight: FloatImage | None = None  # constant: a new alternate, seen once
        self._deviation: FloatImage | None = None  # grey levels: mean |difference| when still
        self._scratch: FloatImage | None = None
        self._previous_gray: GrayImage | None = None
        self._previous_mask: Mask | None = None
        self._previous_raw: Mask | None = None
        self._still_frames: np.ndarray | None = None
        self._frame_index = 0

    def apply(self, gray: GrayImage) -> MotionResult:
        if self._background is None or self._background.shape != gray.shape:
            return self._learn(gray)
        assert self._alternate is not None and self._weight is not None
        assert self._previous_raw is not None and self._deviation is not None
        assert self._previous_gray is not None
        self._frame_index += 1

        gain = self._gain(gray)
        main = cv2.absdiff(gray, cv2.convertScaleAbs(self._background, alpha=gain))
        alternate = cv2.absdiff(gray, cv2.convertScaleAbs(self._alternate, alpha=gain))
        established = cv2.compare(self._weight, _scalar(255.0 * self.mode_weight), cv2.CMP_GE)
        # A pixel's difference is to the nearer mode; a mode not yet
        # established reads as "far" (255).
        difference = cv2.min(main, cv2.bitwise_or(alternate, cv2.bitwise_not(established)))
        self.noise.update(difference)
        threshold = self.threshold

        raw = threshold_difference(difference, threshold)
        if cv2.countNonZero(raw) > self.light_switch_fraction * raw.size:
            result = self._learn(gray)
            return MotionResult(result.mask, difference, threshold, global_change=True)
        per_pixel = self._per_pixel_threshold(threshold)
        mask = self._hysteresis(difference, per_pixel)
        still = cv2.bitwise_not(mask)

        flips = cv2.bitwise_xor(raw, self._previous_raw)
        # Flips (measured at the plain threshold) teach the variability too:
        # without them a pixel that sways past its threshold would never be
        # seen as background, and never learn that it sways.
        teach = cv2.bitwise_or(still, flips)
        if self._frame_index <= self.learning_frames:
            # Learning the scene: the plain mean of every sample so far, not
            # clipped, so swaying is known within one sway instead of after
            # seconds of false alarms. An object that stops or creeps neither
            # is still nor flips, so its inside stays sensitive; nor does a
            # flip deep inside a solid off-background region teach: that is
            # an object stepping in or a ghost being uncovered, not a sway,
            # and teaching it would make the region deaf to itself.
            solid = cv2.erode(raw, self._learning_kernel)
            teach = cv2.bitwise_or(still, cv2.subtract(flips, solid))
            cv2.accumulateWeighted(difference, self._deviation, 1.0 / self._frame_index, mask=teach)
        else:
            cv2.accumulateWeighted(
                cv2.min(difference, per_pixel), self._deviation, self.deviation_rate, mask=teach
            )
        self._update_modes(gray, main, alternate, established, still, threshold)
        changing = threshold_difference(cv2.absdiff(gray, self._previous_gray), threshold)
        self._erode_ghosts(gray, mask, still, changing, threshold)
        if self._frame_index % self.check_every == 0:
            self._absorb_still_regions(gray, mask, changing)
        self._previous_gray = gray
        self._previous_mask = mask
        self._previous_raw = raw
        return MotionResult(mask, difference, threshold)

    def _per_pixel_threshold(self, threshold: float) -> GrayImage:
        """threshold + k * (deviation beyond camera noise), largest in each 3x3.

        Leaves and edges shift by a pixel or so, so a neighbour's
        variability is a pixel's own a moment later.
        """
        assert self._deviation is not None and self._scratch is not None
        k = self.noise.k
        noise_deviation = MEAN_ABS_NOISE * (self.noise.sigma or 0.0)
        cv2.max(self._deviation, _scalar(noise_deviation), dst=self._scratch)
        # Rounded down (the -0.5): "difference > per_pixel" in grey levels
        # then means what it means for the float threshold.
        offset = threshold - k * noise_deviation - 0.5
        per_pixel = cv2.convertScaleAbs(self._scratch, alpha=k, beta=offset)
        return cv2.dilate(per_pixel, self._neighbour_kernel)

    def _hysteresis(self, difference: GrayImage, per_pixel: GrayImage) -> Mask:
        """Strong pixels (above the threshold) and the weaker ones next to them.

        Low-contrast objects (night, camouflage) come out whole instead of in
        fragments, while isolated weak noise pixels stay out.
        """
        strong = cv2.compare(difference, per_pixel, cv2.CMP_GT)
        # Rounded down, as the strong threshold.
        weak_threshold = cv2.convertScaleAbs(per_pixel, alpha=self.weak_fraction, beta=-0.5)
        weak = cv2.compare(difference, weak_threshold, cv2.CMP_GT)
        return cv2.bitwise_and(weak, cv2.dilate(strong, self._grow_kernel))

    def _update_modes(
        self,
        gray: GrayImage,
        main: GrayImage,
        alternate: GrayImage,
        established: Mask,
        still: Mask,
        threshold: float,
    ) -> None:
        """Teach each still pixel's nearer mode; count and seed alternates."""
        assert self._background is not None and self._alternate is not None
        assert self._weight is not None and self._seed_weight is not None
        assert self._previous_mask is not None
        nearer_alternate = cv2.bitwise_and(established, cv2.compare(alternate, main, cv2.CMP_LT))
        cv2.accumulateWeighted(
            gray,
            self._background,
            self.learning_rate,
            mask=cv2.subtract(still, nearer_alternate),
        )
        cv2.accumulateWeighted(
            gray, self._alternate, self.learning_rate, mask=cv2.bitwise_and(still, nearer_alternate)
        )
        # Recurrence: a match counts only right after a background frame.
        matches = cv2.bitwise_and(
            cv2.compare(alternate, _scalar(threshold), cv2.CMP_LE),
            cv2.compare(alternate, main, cv2.CMP_LT),
        )
        cv2.accumulateWeighted(
            cv2.subtract(matches, self._previous_mask),
            self._weight,
            self.mode_rate,
        )
        # A value that matches neither mode replaces a weak alternate.
        unmatched = cv2.subtract(
            threshold_difference(cv2.min(main, alternate), threshold), established
        )
        cv2.accumulateWeighted(gray, self._alternate, 1.0, mask=unmatched)
        cv2.copyTo(self._seed_weight, unmatched, self._weight)

    def _erode_ghosts(
        self, gray: GrayImage, mask: Mask, still: Mask, changing: Mask, threshold: float
    ) -> None:
        """Absorb moving pixels that look like the background right next to them.

        Where something sat in the first frame and left, the uncovered
        background matches its still neighbours: a ghost, which this eats
        from its rim inwards (ViBe's spatial propagation). A real object
        does not match the background around it, so it stays; and since a
        ghost does not change from frame to frame, pixels that change are
        left alone, or the soft rim of a faint moving object would be eaten
        and leave a trail behind it.

        While the scene is being learned the neighbours are sought up to
        three pixels away instead of one. The background is then the first
        frame, so ghosts are to be expected, and the variability learned
        while their object left has made their rim deaf: still, yet keeping
        the object's value in its background, that rim hides the true
        background from a 3x3 search and the ghost would stay for seconds.
        Afterwards the 3x3 search keeps the rims of real objects safe.
        """
        assert self._background is not None
        if not cv2.countNonZero(mask):
            return
        background = cv2.convertScaleAbs(self._background)
        # Moving pixels become 255 for the minimum and 0 for the maximum, so
        # only still neighbours set the range.
        learning = self._frame_index <= self.learning_frames
        kernel = self._learning_kernel if learning else self._neighbour_kernel
        lowest = cv2.erode(cv2.max(background, mask), kernel)
        highest = cv2.dilate(cv2.bitwise_and(background, still), kernel)
        margin = _scalar(threshold * self.weak_fraction)
        inside = cv2.bitwise_and(
            cv2.compare(gray, cv2.subtract(lowest, margin), cv2.CMP_GE),
            cv2.compare(gray, cv2.add(highest, margin), cv2.CMP_LE),
        )
        ghost = cv2.subtract(cv2.bitwise_and(mask, inside), changing)
        cv2.accumulateWeighted(gray, self._background, 1.0, mask=ghost)

    def _learn(self, gray: GrayImage) -> MotionResult:
        """Take this frame as the background (first frame, or after a light switch).

        The variability is kept: which pixels sway is a property of the
        scene, not of its lighting.
        """
        self._background = gray.astype(np.float32)
        self._alternate = self._background.copy()
        self._weight = np.zeros_like(self._background)
        self._seed_weight = np.full_like(self._background, 255.0 * self.mode_rate)
        self._scratch = np.zeros_like(self._background)
        if self._deviation is None or self._deviation.shape != gray.shape:
            self._deviation = np.zeros_like(self._background)
        self._still_frames = np.zeros(gray.shape, np.uint16)
        self._previous_gray = gray
        self._previous_mask = np.zeros_like(gray)
        self._previous_raw = self._previous_mask
        return MotionResult(self._previous_mask, self._previous_mask, self.threshold)

    def _gain(self, gray: GrayImage) -> float:
        """Brightness ratio of frame to background over pixels that look like background.

        Pixels moving in the previous frame are left out, and so are pixels
        far from the background now: an object just entering would
        otherwise drag the ratio. One pixel in 16 is plenty for a ratio of
        means, at a sixteenth of the cost.
        """
        assert self._background is not None and self._previous_mask is not None
        step = GAIN_GRID
        frame = gray[::step, ::step].astype(np.float32)
        background = np.ascontiguousarray(self._background[::step, ::step])
        limit = _scalar(GAIN_INLIERS * self.threshold)
        inliers = cv2.compare(cv2.absdiff(frame, background), limit, cv2.CMP_LT)
        inliers[self._previous_mask[::step, ::step] > 0] = 0
        frame_mean = cv2.mean(frame, mask=inliers)[0]
        background_mean = cv2.mean(background, mask=inliers)[0]
        if background_mean < 1.0 or frame_mean < 1.0:
            return 1.0
        return float(frame_mean / background_mean)

    def _absorb_still_regions(self, gray: GrayImage, mask: Mask, changing: Mask) -> None:
        """Count, per motion region, frames without any change; absorb the stale ones."""
        assert self._still_frames is not None and self._background is not None
        count, labels = cv2.connectedComponents(mask, connectivity=8, ltype=cv2.CV_16U)
        stale_label = np.full(count, 0xFFFF, np.uint16)
        stale_label[0] = 0
        stale_label[labels[changing > 0]] = 0
        # Stale pixels count on, every other pixel restarts at 0.
        self._still_frames += self.check_every
        stale = np.take(stale_label, np.asarray(labels))
        np.bitwise_and(self._still_frames, stale, out=self._still_frames)
        absorb = cv2.compare(self._still_frames, _scalar(self.absorb_after), cv2.CMP_GE)
        if cv2.countNonZero(absorb):
            cv2.accumulateWeighted(gray, self._background, 1.0, mask=absorb)
            self._still_frames[absorb > 0] = 0

    def reset(self) -> None:
        super().reset()
        self._background = None
        self._alternate = None
        self._weight = None
        self._seed_weight = None
        self._deviation = None
        self._scratch = None
        self._previous_gray = None
        self._previous_mask = None
        self._previous_raw = None
        self._still_frames = None
        self._frame_index = 0
