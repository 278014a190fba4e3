"""The one small interface every segmentation method implements."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import cv2

from app.vision.noise import NoiseEstimator
from app.vision.scene_background import SceneBackground
from app.vision.types import GrayImage, Mask


@dataclass(frozen=True, slots=True)
class MotionResult:
    """What a method found in one frame.

    ``mask`` is 255 where something moves; ``difference`` is the grey-level
    change the method thresholded (the paper's difference image, for
    snapshots and for tuning the sensitivity by eye); ``global_change`` is
    True when the whole view changed at once (a light switched, the camera
    moved) and the method re-learned it, or moved its model with it, instead
    of reporting the change as motion.
    """

    mask: Mask
    difference: GrayImage
    threshold: float
    global_change: bool = False


REFERENCE_FPS = 25.0
"""The frame rate a method's counts of frames are given at: at the video's own rate
(``fps``), a count that stands for a time is scaled to last as long (``in_frames``)."""


def in_frames(count: int, fps: float) -> int:
    """``count`` frames at ``REFERENCE_FPS``, as frames at ``fps`` lasting as long (one
    at least)."""
    return max(1, round(count * fps / REFERENCE_FPS))


class MotionMethod(ABC):
    """Segmentation: grey frame in, motion mask out.

    ``sensitivity`` is the grey-level threshold (1..255; lower is more
    sensitive). ``None`` means automatic: the threshold follows the noise
    measured in the method's own difference image. ``fps``: the video's frame rate.
    """

    name: ClassVar[str]
    description: ClassVar[str]
    starts_from_scene: ClassVar[bool] = False
    """Whether ``seed`` takes a scene (the others learn from the first frame whatever
    they are given)."""
    judges_whole_view: ClassVar[bool] = False
    """Whether the method tells a change of the whole view (a light switched, the camera
    knocked) from motion itself (``global_change``): what it calls motion over most of
    the view then is motion (something covering the lens). Of the others' such frames
    the pipeline reports nothing."""

    def __init__(self, sensitivity: float | None = None, fps: float = REFERENCE_FPS) -> None:
        self.noise = NoiseEstimator()
        self.sensitivity = sensitivity
        self.fps = fps

    @property
    def sensitivity(self) -> float | None:
        return self._sensitivity

    @sensitivity.setter
    def sensitivity(self, value: float | None) -> None:
        if value is not None and not 1 <= value <= 255:
            raise ValueError(f"sensitivity must be between 1 and 255 grey levels, not {value}")
        self._sensitivity = value
        self._sensitivity_changed()

    def _sensitivity_changed(self) -> None:  # noqa: B027  (an optional hook, not abstract)
        """Hook for methods whose model must hear of a new sensitivity at once."""

    @property
    def threshold(self) -> float:
        """The grey-level threshold in force for the next frame."""
        return self._sensitivity if self._sensitivity is not None else self.noise.threshold

    def seed(self, scene: SceneBackground) -> None:
        """Start from ``scene`` (estimated ahead or just before) rather than from the first
        frame, where the method ``starts_from_scene``: the first frame given to ``apply``
        after this is compared with the scene; ``reset`` forgets it."""
        raise NotImplementedError(f"{self.name} learns its scene from the first frame")

    @abstractmethod
    def apply(self, gray: GrayImage) -> MotionResult:
        """Segment one frame; frames must arrive in order and keep their size."""

    def set_fps(self, fps: float) -> None:
        """The video's frame rate as measured since the method was made (a live
        camera's): what it counts in frames is counted at that rate from now on."""
        self.fps = fps

    def reset(self) -> None:
        """Forget the scene (a new source, or a jump in the video)."""
        self.noise.reset()


def threshold_difference(difference: GrayImage, threshold: float) -> Mask:
    """Binary image: 255 where the difference exceeds the threshold."""
    _, mask = cv2.threshold(difference, threshold, 255, cv2.THRESH_BINARY)
    return mask
