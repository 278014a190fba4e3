"""Clean a binary motion mask: drop speckles, then join the parts of one object."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from app.vision.types import Mask


@dataclass(frozen=True)
class Morphology:
    """Opening removes isolated noise pixels; closing fills holes and joins fragments."""

    open_kernel: int = 3
    close_kernel: int = 5

    @cached_property
    def _open(self) -> np.ndarray | None:
        return _ellipse(self.open_kernel)

    @cached_property
    def _close(self) -> np.ndarray | None:
        return _ellipse(self.close_kernel)

    def __call__(self, mask: Mask) -> Mask:
        if self._open is not None:
            mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, self._open)
        if self._close is not None:
            mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, self._close)
        return mask


def _ellipse(size: int) -> np.ndarray | None:
    if size <= 1:
        return None
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
