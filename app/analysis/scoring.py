"""Scoring an analysis against ground truth: the paper's DR/FAR and CDnet's pixel metrics."""

from __future__ import annotations

from typing import Any

from app.analysis.metrics import ObjectCounts, PixelCounts
from app.analysis.truth import Truth
from app.vision.detections import Box
from app.vision.preprocess import to_size
from app.vision.types import Mask

WARM_UP_FRAMES = 20
"""Frames a background model gets to learn before scores 'after warm-up' count."""


class Scorer:
    """DR/FAR per object per frame, and CDnet pixel metrics when truth is masks."""

    def __init__(self, truth: Truth, min_area: float, size: tuple[int, int]) -> None:
        """``size``: the input's (width, height), which reported boxes are in."""
        self.truth = truth
        self.min_area = min_area
        self.size = size
        self.objects, self.objects_warm = ObjectCounts(), ObjectCounts()
        self.pixels, self.pixels_warm = PixelCounts(), PixelCounts()
        self.frames_scored = 0

    def add(self, index: int, boxes: list[Box], mask: Mask | None) -> None:
        """Score one frame's reported boxes and (when truth has masks) its motion mask."""
        if index not in self.truth.mask_paths and index not in self.truth.boxes:
            return
        self.frames_scored += 1
        warm = index >= WARM_UP_FRAMES
        true_boxes = self.truth.boxes_at(index, self.min_area, self.size)
        self.objects.add(true_boxes, boxes)
        if warm:
            self.objects_warm.add(true_boxes, boxes)
        label = self.truth.mask(index) if mask is not None else None
        if label is not None and mask is not None:
            size = (label.shape[1], label.shape[0])
            mask = to_size(mask, size)
            roi = to_size(self.truth.roi, size) if self.truth.roi is not None else None
            self.pixels.add(mask, label, roi)
            if warm:
                self.pixels_warm.add(mask, label, roi)

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "source": self.truth.source,
            "kind": self.truth.kind,
            "frames_scored": self.frames_scored,
            "warm_up_frames": WARM_UP_FRAMES,
            # The paper's two figures up front (all frames); the detail follows.
            "detection_rate": self.objects.detection_rate,
            "false_alarm_rate": self.objects.false_alarm_rate,
            "objects": self.objects.as_dict(),
            "objects_after_warm_up": self.objects_warm.as_dict(),
        }
        if self.pixels.tp + self.pixels.fp + self.pixels.tn + self.pixels.fn:
            out["pixels"] = self.pixels.as_dict()
            out["pixels_after_warm_up"] = self.pixels_warm.as_dict()
        return out
