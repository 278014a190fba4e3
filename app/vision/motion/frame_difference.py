"""The paper's method: absolute difference against the previous frame."""

from __future__ import annotations

import cv2
import numpy as np

from app.vision.motion.base import REFERENCE_FPS, MotionMethod, MotionResult, threshold_difference
from app.vision.types import GrayImage


class FrameDifference(MotionMethod):
    name = "frame-difference"
    description = "the paper's two-frame difference: fast, misses slow and uniform objects"

    def __init__(self, sensitivity: float | None = None, fps: float = REFERENCE_FPS) -> None:
        super().__init__(sensitivity, fps)
        self._previous: GrayImage | None = None

    def apply(self, gray: GrayImage) -> MotionResult:
        previous, self._previous = self._previous, gray
        if previous is None:
            still = np.zeros_like(gray)
            return MotionResult(still, still, self.threshold)
        difference = cv2.absdiff(gray, previous)
        self.noise.update(difference, gray)
        threshold = self.threshold
        return MotionResult(threshold_difference(difference, threshold), difference, threshold)

    def reset(self) -> None:
        super().reset()
        self._previous = None
