"""Where a motion mask holds anything: most of a frame holds nothing, and the steps after
segmentation look only there."""

from __future__ import annotations

import cv2

from app.vision.types import Mask

Slices = tuple[slice, slice]
"""Rows, columns: index an image with it."""


def motion_box(mask: Mask, margin: int) -> Slices | None:
    """The box of ``mask``'s set pixels, ``margin`` pixels wider each way where the frame
    allows (a step that reads past a pixel sees what it would in the whole frame); None
    where no pixel is set."""
    x, y, w, h = cv2.boundingRect(mask)
    if w == 0:
        return None
    return (
        slice(max(y - margin, 0), y + h + margin),
        slice(max(x - margin, 0), x + w + margin),
    )
