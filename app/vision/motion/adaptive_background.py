"""Vigil's default: an adaptive background model that is cheap and hard to fool.

A running-average background (the classic of Motion and of OpenCV's
``accumulateWeighted``) with four additions, each aimed at a known failure:

* **Selective update** — pixels that move do not teach the background, so a
  slow, uniform object is not absorbed while it crosses (frame difference's
  weak spot).
* **Gain compensation and light-switch handling** — the background is scaled
  to the frame's brightness each frame (auto-exposure, clouds); a change that
  still covers most of the scene is re-learned at once instead of reported.
* **Blinking pixels** — a pixel that flips between motion and stillness from
  frame to frame (leaves, water, flicker) raises its own threshold, the idea
  of SuBSENSE's blink feedback (St-Charles et al., 2015).
* **Ghost absorption** — a region that stays "moving" without any change
  between consecutive frames is a ghost (something that was in the first
  frame and left) or an object that stopped; after ``absorb_after`` frames it
  becomes background.
"""

from __future__ import annotations

import cv2
import numpy as np

from app.vision.motion.base import MotionMethod, MotionResult, threshold_difference
from app.vision.types import FloatImage, GrayImage, Mask


class AdaptiveBackground(MotionMethod):
    name = "adaptive"
    description = "selective running average with light-switch, flicker and ghost handling (default)"

    def __init__(
        self,
        sensitivity: float | None = None,
        learning_rate: float = 0.03,
        light_switch_fraction: float = 0.5,
        blink_rate: float = 0.1,
        blink_gain: float = 6.0,
        weak_fraction: float = 0.5,
        absorb_after: int = 30,
        check_every: int = 3,
    ) -> None:
        super().__init__(sensitivity)
        self.learning_rate = learning_rate
        self.light_switch_fraction = light_switch_fraction
        self.blink_rate = blink_rate
        self.blink_gain = blink_gain
        self.weak_fraction = weak_fraction
        self._grow_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))
        self._neighbour_kernel = np.ones((3, 3), np.uint8)
        self.absorb_after = absorb_after
        self.check_every = check_every
        self._background: FloatImage | None = None
        self._blink: FloatImage | None = None  # 0..255: how often each pixel flips
        self._previous_gray: GrayImage | None = None
        self._previous_mask: Mask | None = None
        self._previous_raw: Mask | None = None
        self._still_frames: np.ndarray | None = None
        self._frame_index = 0

    def apply(self, gray: GrayImage) -> MotionResult:
        frame = gray.astype(np.float32)
        if self._background is None or self._background.shape != frame.shape:
            return self._learn(gray, frame)
        background = self._background
        assert self._previous_mask is not None and self._blink is not None
        assert self._previous_raw is not None
        self._frame_index += 1

        still = cv2.bitwise_not(self._previous_mask)
        reference = background * self._gain(frame, background, still)
        difference = cv2.convertScaleAbs(cv2.absdiff(frame, reference))
        self.noise.update(difference)
        threshold = self.threshold

        raw = threshold_difference(difference, threshold)
        if cv2.countNonZero(raw) > self.light_switch_fraction * raw.size:
            result = self._learn(gray, frame)
            return MotionResult(result.mask, difference, threshold, global_change=True)
        # Blinking is measured at the plain threshold, so raising a pixel's own
        # threshold does not feed back into how often it is seen to blink.
        cv2.accumulateWeighted(cv2.bitwise_xor(raw, self._previous_raw), self._blink, self.blink_rate)
        per_pixel = threshold * (1.0 + (self.blink_gain / 255.0) * self._blink)
        mask = self._hysteresis(difference, per_pixel)

        cv2.accumulateWeighted(frame, background, self.learning_rate, mask=cv2.bitwise_not(mask))
        self._erode_ghosts(frame, mask, threshold)
        if self._frame_index % self.check_every == 0:
            self._absorb_still_regions(gray, frame, mask, threshold)
        self._previous_gray = gray
        self._previous_mask = mask
        self._previous_raw = raw
        return MotionResult(mask, difference, threshold)

    def _hysteresis(self, difference: GrayImage, per_pixel: FloatImage) -> Mask:
        """Strong pixels (above the threshold) and the weaker ones next to them.

        Low-contrast objects (night, camouflage) come out whole instead of in
        fragments, while isolated weak noise pixels stay out.
        """
        diff = difference.astype(np.float32)
        strong = np.where(diff > per_pixel, np.uint8(255), np.uint8(0))
        weak = np.where(diff > per_pixel * self.weak_fraction, np.uint8(255), np.uint8(0))
        near_strong = cv2.dilate(strong, self._grow_kernel)
        return cv2.bitwise_and(weak, near_strong)

    def _erode_ghosts(self, frame: FloatImage, mask: Mask, threshold: float) -> None:
        """Absorb moving pixels that look like the background right next to them.

        Where something sat in the first frame and left, the uncovered
        background matches its still neighbours: a ghost, which this eats
        from its rim inwards (ViBe's spatial propagation). A real object
        does not match the background around it, so it stays.
        """
        assert self._background is not None
        if not cv2.countNonZero(mask):
            return
        moving = mask > 0
        lowest = self._background.copy()
        lowest[moving] = 1e6
        highest = self._background.copy()
        highest[moving] = -1e6
        lowest = cv2.erode(lowest, self._neighbour_kernel)
        highest = cv2.dilate(highest, self._neighbour_kernel)
        margin = threshold * self.weak_fraction
        matches = moving & (frame >= lowest - margin) & (frame <= highest + margin)
        self._background[matches] = frame[matches]

    def _learn(self, gray: GrayImage, frame: FloatImage) -> MotionResult:
        """Take this frame as the background (first frame, or after a light switch)."""
        self._background = frame.copy()
        if self._blink is None or self._blink.shape != frame.shape:
            self._blink = np.zeros_like(frame)
        self._still_frames = np.zeros(frame.shape, np.uint16)
        self._previous_gray = gray
        self._previous_mask = np.zeros_like(gray)
        self._previous_raw = self._previous_mask
        return MotionResult(self._previous_mask, self._previous_mask, self.threshold)

    @staticmethod
    def _gain(frame: FloatImage, background: FloatImage, still: Mask) -> float:
        """Brightness ratio of frame to background over the pixels that were still."""
        frame_mean = cv2.mean(frame, mask=still)[0]
        background_mean = cv2.mean(background, mask=still)[0]
        if background_mean < 1.0 or frame_mean < 1.0:
            return 1.0
        return float(frame_mean / background_mean)

    def _absorb_still_regions(
        self, gray: GrayImage, frame: FloatImage, mask: Mask, threshold: float
    ) -> None:
        """Count, per motion region, frames without any change; absorb the stale ones."""
        assert self._previous_gray is not None and self._still_frames is not None
        count, labels = cv2.connectedComponents(mask, connectivity=8)
        if count <= 1:
            self._still_frames[:] = 0
            return
        changing = threshold_difference(cv2.absdiff(gray, self._previous_gray), threshold)
        active = np.zeros(count, bool)
        active[0] = True
        active[np.unique(labels[(changing > 0) & (mask > 0)])] = True
        stale = ~active[labels]
        self._still_frames[~stale] = 0
        self._still_frames[stale] += self.check_every
        absorb = self._still_frames >= self.absorb_after
        if absorb.any():
            assert self._background is not None
            self._background[absorb] = frame[absorb]
            self._still_frames[absorb] = 0

    def reset(self) -> None:
        super().reset()
        self._background = None
        self._blink = None
        self._previous_gray = None
        self._previous_mask = None
        self._previous_raw = None
        self._still_frames = None
        self._frame_index = 0
