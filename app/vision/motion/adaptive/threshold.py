"""Each pixel's own threshold, and hysteresis.

The plain threshold is the sensitivity, or automatic: ``k`` times the camera noise the
method measures (``app.vision.noise``). Deviation beyond what that noise explains (a
pixel's variability, ``learning``), taken as the largest in the pixel's 3x3
neighbourhood (a leaf's variability is its neighbour's a moment later), raises the
pixel's threshold by the same ``k``: leaves and water get deaf, still pixels keep the
plain threshold. **Hysteresis**: pixels above a fraction of their threshold count too
where a pixel above it is near, so low-contrast objects come out whole and weak noise
stays out. A grey level is compared with a threshold as OpenCV's ``threshold`` does
(``difference > floor(threshold)``).
"""

from __future__ import annotations

import math

import numpy as np

from app.vision.compiled import compiled_helper
from app.vision.types import FloatImage, GrayImage, Mask

MAX_GREY = np.float32(255.0)

MEAN_ABS_NOISE = math.sqrt(2.0 / math.pi)
"""E|X| / sigma for Gaussian X: the mean deviation that camera noise alone gives."""


@compiled_helper
def limit_row(
    deviation: FloatImage,
    y: int,
    noise_deviation: np.float32,
    k: np.float32,
    offset: np.float32,
    out: GrayImage,
) -> None:
    """A pixel's own threshold before the neighbourhood's largest: ``k`` x
    max(deviation, noise) + ``offset``, to a grey level (never below the plain one)."""
    for x in range(deviation.shape[1]):
        spread = max(deviation[y, x], noise_deviation)
        out[x] = np.uint8(min(np.floor(spread * k + offset), MAX_GREY))


@compiled_helper
def above_each_row(values: GrayImage, limits: GrayImage, out: Mask) -> None:
    """255 where a value is above its own limit, else 0."""
    for x in range(values.size):
        out[x] = np.uint8(255) if values[x] > limits[x] else np.uint8(0)
