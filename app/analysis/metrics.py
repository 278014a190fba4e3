"""Quality against ground truth.

* The paper's object-level rates, counted per object per frame:
  Detection Rate DR = TP / (TP + FN) and False Alarm Rate FAR = FP / (TP + FP),
  a detection matching a true box when their overlap (IoU) reaches a bar.
* The CDnet 2014 pixel metrics (Wang et al., CVPR Workshops 2014): only
  pixels labelled 0 (static) or 255 (moving) are scored, inside the ROI.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from app.vision.detections import Box
from app.vision.types import Mask

DEFAULT_IOU = 0.3


@dataclass
class ObjectCounts:
    tp: int = 0
    fp: int = 0
    fn: int = 0

    @property
    def detection_rate(self) -> float | None:
        return self.tp / (self.tp + self.fn) if self.tp + self.fn else None

    @property
    def false_alarm_rate(self) -> float | None:
        return self.fp / (self.tp + self.fp) if self.tp + self.fp else None

    def add(self, truth: Sequence[Box], detected: Sequence[Box], iou: float = DEFAULT_IOU) -> None:
        matched = len(match_boxes(truth, detected, iou))
        self.tp += matched
        self.fn += len(truth) - matched
        self.fp += len(detected) - matched

    def as_dict(self) -> dict[str, float | int | None]:
        return {
            "tp": self.tp,
            "fp": self.fp,
            "fn": self.fn,
            "detection_rate": self.detection_rate,
            "false_alarm_rate": self.false_alarm_rate,
        }


def match_boxes(
    truth: Sequence[Box], detected: Sequence[Box], iou: float = DEFAULT_IOU
) -> list[tuple[int, int]]:
    """One-to-one pairs (truth index, detection index) maximising total overlap."""
    if not truth or not detected:
        return []
    overlap = np.array([[t.iou(d) for d in detected] for t in truth])
    rows, cols = linear_sum_assignment(-overlap)
    return [(int(r), int(c)) for r, c in zip(rows, cols, strict=True) if overlap[r, c] >= iou]


@dataclass
class PixelCounts:
    tp: int = 0
    fp: int = 0
    tn: int = 0
    fn: int = 0

    def add(self, mask: Mask, truth: Mask, roi: Mask | None = None) -> None:
        """Score one motion mask (255 = motion) against a CDnet label image."""
        if mask.shape != truth.shape:
            raise ValueError(f"mask {mask.shape} and ground truth {truth.shape} differ in size")
        scored = (truth == 0) | (truth == 255)
        if roi is not None:
            scored &= roi > 0
        moving = mask > 0
        positive = truth == 255
        self.tp += int(np.count_nonzero(scored & moving & positive))
        self.fp += int(np.count_nonzero(scored & moving & ~positive))
        self.fn += int(np.count_nonzero(scored & ~moving & positive))
        self.tn += int(np.count_nonzero(scored & ~moving & ~positive))

    @property
    def recall(self) -> float:
        return _ratio(self.tp, self.tp + self.fn)

    @property
    def specificity(self) -> float:
        return _ratio(self.tn, self.tn + self.fp)

    @property
    def fpr(self) -> float:
        return _ratio(self.fp, self.fp + self.tn)

    @property
    def fnr(self) -> float:
        return _ratio(self.fn, self.tp + self.fn)

    @property
    def pwc(self) -> float:
        """Percentage of wrong classifications."""
        return 100.0 * _ratio(self.fn + self.fp, self.tp + self.fn + self.fp + self.tn)

    @property
    def precision(self) -> float:
        return _ratio(self.tp, self.tp + self.fp)

    @property
    def f_measure(self) -> float:
        p, r = self.precision, self.recall
        return 2 * p * r / (p + r) if p + r else 0.0

    def as_dict(self) -> dict[str, float | int]:
        return {
            "tp": self.tp,
            "fp": self.fp,
            "tn": self.tn,
            "fn": self.fn,
            "recall": self.recall,
            "specificity": self.specificity,
            "fpr": self.fpr,
            "fnr": self.fnr,
            "pwc": self.pwc,
            "precision": self.precision,
            "f_measure": self.f_measure,
        }


def _ratio(num: int, den: int) -> float:
    return num / den if den else 0.0
