"""Segmentation methods behind one interface, looked up by name."""

from __future__ import annotations

from app.vision.motion.adaptive import AdaptiveBackground
from app.vision.motion.base import REFERENCE_FPS, MotionMethod, MotionResult
from app.vision.motion.frame_difference import FrameDifference
from app.vision.motion.opencv_subtractors import KNN, MOG2
from app.vision.motion.three_frame_difference import ThreeFrameDifference

METHODS: dict[str, type[MotionMethod]] = {
    cls.name: cls for cls in (AdaptiveBackground, FrameDifference, ThreeFrameDifference, MOG2, KNN)
}
DEFAULT_METHOD = AdaptiveBackground.name


def create_method(
    name: str, sensitivity: float | None = None, fps: float = REFERENCE_FPS
) -> MotionMethod:
    """A fresh method by its public name (``vigil analyze --method NAME``), for a video
    of ``fps`` frames a second."""
    try:
        cls = METHODS[name]
    except KeyError:
        raise ValueError(f"unknown method {name!r}; choose from {', '.join(METHODS)}") from None
    return cls(sensitivity=sensitivity, fps=fps)


__all__ = ["DEFAULT_METHOD", "METHODS", "MotionMethod", "MotionResult", "create_method"]
