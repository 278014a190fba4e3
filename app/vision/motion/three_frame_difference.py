"""Three-frame difference: a pixel moves only if it differs from both earlier frames.

Two-frame differencing marks where the object *was* as well as where it
*is*; requiring a change against both t-1 and t-2 drops most of that ghost.
"""

from __future__ import annotations

from collections import deque

import cv2
import numpy as np

from app.vision.motion.base import REFERENCE_FPS, MotionMethod, MotionResult, threshold_difference
from app.vision.types import GrayImage


class ThreeFrameDifference(MotionMethod):
    name = "three-frame"
    description = "difference against the two previous frames: fewer ghosts than two-frame"

    def __init__(self, sensitivity: float | None = None, fps: float = REFERENCE_FPS) -> None:
        super().__init__(sensitivity, fps)
        self._history: deque[GrayImage] = deque(maxlen=2)

    def apply(self, gray: GrayImage) -> MotionResult:
        history = list(self._history)
        self._history.append(gray)
        if len(history) < 2:
            still = np.zeros_like(gray)
            return MotionResult(still, still, self.threshold)
        older, previous = history
        recent = cv2.absdiff(gray, previous)
        self.noise.update(recent, gray)
        threshold = self.threshold
        difference = cv2.min(recent, cv2.absdiff(gray, older))
        return MotionResult(threshold_difference(difference, threshold), difference, threshold)

    def reset(self) -> None:
        super().reset()
        self._history.clear()
