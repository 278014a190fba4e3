"""Clean a binary motion mask: drop speckles, then join the parts of one object."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from app.vision.mask_box import motion_box
from app.vision.types import Mask


@dataclass(frozen=True)
class Morphology:
    """Opening removes isolated noise pixels; closing fills holes and joins fragments.

    Only the part of the mask around its motion is cleaned (most of a frame holds
    none): neither step can set a pixel outside the box of the motion, and with a
    margin past both steps' reach, the part's edge is never read.
    """

    open_kernel: int = 3
    close_kernel: int = 5

    @cached_property
    def _open(self) -> np.ndarray | None:
        return _ellipse(self.open_kernel)

    @cached_property
    def _close(self) -> np.ndarray | None:
        return _ellipse(self.close_kernel)

    @cached_property
    def _margin(self) -> int:
        # Opening reads its reach past a pixel; closing's erosion reads its reach past
        # the dilation's, which reaches as far again.
        return self.open_kernel // 2 + 2 * (self.close_kernel // 2) + 1

    def __call__(self, mask: Mask) -> Mask:
        cleaned = np.zeros_like(mask)
        box = motion_box(mask, self._margin)
        if box is None:
            return cleaned
        part = mask[box]
        if self._open is not None:
            part = cv2.morphologyEx(part, cv2.MORPH_OPEN, self._open)
        if self._close is not None:
            part = cv2.morphologyEx(part, cv2.MORPH_CLOSE, self._close)
        cleaned[box] = part
        return cleaned


def _ellipse(size: int) -> np.ndarray | None:
    if size <= 1:
        return None
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
