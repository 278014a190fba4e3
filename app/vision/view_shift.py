"""A view that shifted in the picture (a knocked camera): moving images by it, and
whether it explains how one picture differs from another."""

from __future__ import annotations

import math

import cv2
import numpy as np

SHIFT_EXPLAINS = 0.25
"""A shift explains a change when, with the reference moved by it, at most this share of
the pixels that differed still differ (the objects in view)."""


def shifted(
    image: np.ndarray, dx: float, dy: float, into: np.ndarray, smooth: bool = True
) -> np.ndarray:
    """``image`` moved (dx, dy) pixels, drawn over ``into``, which shows where nothing of
    ``image`` lands: bilinear (``smooth``, for grey levels), or nearest (masks, counts)."""
    move = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]])
    flags = cv2.INTER_LINEAR if smooth else cv2.INTER_NEAREST
    size = (image.shape[1], image.shape[0])
    return cv2.warpAffine(
        image, move, size, dst=into, flags=flags, borderMode=cv2.BORDER_TRANSPARENT
    )


def shift_explains(
    reference: np.ndarray,
    picture: np.ndarray,
    dx: float,
    dy: float,
    threshold: float,
    step: int = 1,
) -> bool:
    """Whether ``reference`` (float32 grey levels) moved (dx, dy) explains how ``picture``
    differs from it by more than ``threshold``: compared where both views see the scene,
    on every ``step``-th row and column, the pixels that differ are some, and at most
    ``SHIFT_EXPLAINS`` of them still differ from the moved reference. False where the
    views share no pixel."""
    height, width = reference.shape
    margin_x, margin_y = math.ceil(abs(dx)) + 1, math.ceil(abs(dy)) + 1
    inside = (
        slice(margin_y, height - margin_y, step),
        slice(margin_x, width - margin_x, step),
    )
    moved = shifted(reference, dx, dy, np.zeros_like(reference))
    before = np.count_nonzero(np.abs(picture[inside] - reference[inside]) > threshold)
    after = np.count_nonzero(np.abs(picture[inside] - moved[inside]) > threshold)
    return bool(before and after <= SHIFT_EXPLAINS * before)
