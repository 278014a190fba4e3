"""Automatic sensitivity: estimate the camera's noise and set the threshold from it.

The paper notes that the threshold decides everything. A fixed grey-level
threshold is too deaf on a clean camera and too jumpy on a noisy night one,
so by default each method thresholds its own difference image at ``k`` robust
standard deviations of that image's noise.

For still pixels a difference image is (close to) the absolute value of a
zero-mean Gaussian, whose median is 0.6745 sigma. The median stays put while
fewer than half the pixels move, so moving objects barely shift the estimate.
"""

from __future__ import annotations

import numpy as np

from app.vision.compiled import compiled
from app.vision.types import GrayImage, Mask

HALF_NORMAL_MEDIAN = 0.6745

DIM_GREY = 64.0
"""Mean grey below which the threshold's floor comes down with the scene's brightness."""

DARK_FLOOR_SHARE = 0.5
"""The least share of its floor the threshold keeps, however dark the scene."""

FEWEST_STILL = 0.05
"""The least share of a frame's pixels, still, that the noise is measured on."""

BRIGHTNESS_STEP = 4
"""The scene's brightness is measured on every BRIGHTNESS_STEP-th row and column."""


def noise_sigma(difference: GrayImage, moving: Mask | None = None) -> float | None:
    """Robust noise standard deviation of an absolute difference image (8-bit), over
    the pixels that are not ``moving`` (nonzero there); None where too few are left
    to tell (``FEWEST_STILL``)."""
    if difference.dtype != np.uint8:
        raise ValueError(f"needs an 8-bit difference image, not {difference.dtype}")
    difference = np.ascontiguousarray(difference)
    level = _median_level(difference, difference if moving is None else moving, moving is not None)
    if level is None:
        return None
    return max(0.0, level) / HALF_NORMAL_MEDIAN


@compiled
def _median_level(difference: GrayImage, moving: Mask, skip_moving: bool) -> float | None:
    """The median grey level, interpolated inside its bin (integer levels would round a
    clean camera's noise to exactly 0 or 1), of every other row and column (a quarter
    of the pixels estimates it as well, at a quarter of the cost), leaving out the
    ``moving`` pixels if ``skip_moving``."""
    # Four histograms, a column in four each: a run of pixels of one level would
    # otherwise wait on its own count, one add after another.
    histograms = np.zeros((4, 256), np.int64)
    rows, cols = difference.shape
    for y in range(0, rows, 2):
        for x in range(0, cols, 2):
            kept = not skip_moving or moving[y, x] == 0
            histograms[(x >> 1) & 3, difference[y, x]] += kept
    counts = histograms.sum(axis=0)
    counted = counts.sum()
    if counted < FEWEST_STILL * ((rows + 1) // 2) * ((cols + 1) // 2):
        return None
    half = counted / 2.0
    below = 0
    for level in range(256):
        if below + counts[level] >= half:
            return level + (half - below) / max(counts[level], 1) - 0.5
        below += counts[level]
    return 255.5


class NoiseEstimator:
    """Running noise estimate, refreshed every few frames and smoothed over time.

    The threshold never goes below a floor, whatever the noise: on a clean
    camera, compression blocks and light flicker would pass a threshold of a
    few k sigma. Both scale with the light, so in a dark scene (mean grey under
    ``DIM_GREY``) the floor comes down in proportion, to ``DARK_FLOOR_SHARE`` of
    itself: a night camera with noise reduction shows people a few grey levels
    from the background, which a bright scene's floor would hide.
    """

    def __init__(
        self,
        k: float = 4.0,
        floor: float = 10.0,
        ceiling: float = 60.0,
        every: int = 4,
        smoothing: float = 0.2,
    ) -> None:
        self.k = k
        self.floor = floor
        self.ceiling = ceiling
        self.every = every
        self.smoothing = smoothing
        self.sigma: float | None = None
        self.brightness: float | None = None
        """The scene's mean grey level."""
        self._count = 0

    def update(self, difference: GrayImage, gray: GrayImage, moving: Mask | None = None) -> None:
        """``difference``: the method's difference image; ``gray``: the frame; ``moving``:
        where something moved (nonzero), if the method knows, left out of the estimate:
        an object that fills most of the view would otherwise be taken for noise."""
        self._count += 1
        if self.sigma is not None and self._count % self.every:
            return
        sigma = noise_sigma(difference, moving)
        if sigma is None:
            return
        brightness = float(gray[::BRIGHTNESS_STEP, ::BRIGHTNESS_STEP].mean()) if gray.size else 0.0
        if self.sigma is None or self.brightness is None:  # Both, or neither (for mypy).
            self.sigma, self.brightness = sigma, brightness
        else:
            self.sigma += self.smoothing * (sigma - self.sigma)
            self.brightness += self.smoothing * (brightness - self.brightness)

    @property
    def threshold(self) -> float:
        """Grey-level threshold: k sigma, kept within [floor, ceiling], the floor lower in
        a dark scene."""
        sigma = self.sigma if self.sigma is not None else 0.0
        brightness = self.brightness if self.brightness is not None else DIM_GREY
        floor = self.floor * min(1.0, max(DARK_FLOOR_SHARE, brightness / DIM_GREY))
        return float(min(self.ceiling, max(floor, self.k * sigma)))

    def reset(self) -> None:
        self.sigma = None
        self.brightness = None
        self._count = 0
