"""OpenCV's Gaussian-mixture (MOG2) and k-nearest-neighbour (KNN) models as methods."""

from __future__ import annotations

from typing import Any

import cv2

from app.vision.motion.base import REFERENCE_FPS, MotionMethod, MotionResult
from app.vision.types import GrayImage

# Without a sensitivity each model keeps OpenCV's own tuned default; with one,
# the grey-level threshold is translated into the model's distance measure.
MOG2_TYPICAL_NOISE_SIGMA = 3.0


class _OpenCVSubtractor(MotionMethod):
    def __init__(self, sensitivity: float | None = None, fps: float = REFERENCE_FPS) -> None:
        self._model: Any = None
        super().__init__(sensitivity, fps)
        self._model = self._create()

    def _create(self) -> Any:
        model = self._new_model()
        self._configure(model)
        return model

    def _new_model(self) -> Any:
        raise NotImplementedError

    def _configure(self, model: Any) -> None:
        raise NotImplementedError

    def _sensitivity_changed(self) -> None:
        if self._model is not None:
            self._configure(self._model)

    def apply(self, gray: GrayImage) -> MotionResult:
        mask = self._model.apply(gray)
        # Shadows (127) are not motion.
        _, mask = cv2.threshold(mask, 200, 255, cv2.THRESH_BINARY)
        background = self._model.getBackgroundImage()
        difference = cv2.absdiff(gray, background) if background is not None else mask
        return MotionResult(mask, difference, self.threshold)

    @property
    def threshold(self) -> float:
        return self._sensitivity if self._sensitivity is not None else 0.0

    def reset(self) -> None:
        super().reset()
        self._model = self._create()


class MOG2(_OpenCVSubtractor):
    name = "mog2"
    description = "OpenCV's adaptive Gaussian mixture (Zivkovic 2004)"

    def _new_model(self) -> Any:
        return cv2.createBackgroundSubtractorMOG2(detectShadows=False)

    def _configure(self, model: Any) -> None:
        if self._sensitivity is None:
            model.setVarThreshold(16.0)
        else:
            model.setVarThreshold((self._sensitivity / MOG2_TYPICAL_NOISE_SIGMA) ** 2)


class KNN(_OpenCVSubtractor):
    name = "knn"
    description = "OpenCV's k-nearest-neighbour background model (Zivkovic 2006)"

    def _new_model(self) -> Any:
        return cv2.createBackgroundSubtractorKNN(detectShadows=False)

    def _configure(self, model: Any) -> None:
        model.setDist2Threshold(400.0 if self._sensitivity is None else self._sensitivity**2)
