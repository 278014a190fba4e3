"""Automatic sensitivity: estimate the camera's noise and set the threshold from it.

The paper notes that the threshold decides everything. A fixed grey-level
threshold is too deaf on a clean camera and too jumpy on a noisy night one,
so by default each method thresholds its own difference image at ``k`` robust
standard deviations of that image's noise.

For still pixels a difference image is (close to) the absolute value of a
zero-mean Gaussian, whose quantile ``q`` is a fixed multiple of sigma (the
median, q = 0.5, is 0.6745 sigma). A quantile stays put while fewer than
``1 - q`` of the pixels move, so moving objects barely shift the estimate; a
lower quantile tolerates scenes where most pixels sway (trees, water).
"""

from __future__ import annotations

from statistics import NormalDist

import cv2
import numpy as np

from app.vision.types import GrayImage

HALF_NORMAL_MEDIAN = 0.6745


def half_normal_quantile(quantile: float) -> float:
    """The ``quantile`` of |X| for X ~ N(0, 1), in units of sigma."""
    return NormalDist().inv_cdf((1.0 + quantile) / 2.0)


def noise_sigma(difference: GrayImage, quantile: float = 0.5) -> float:
    """Robust noise standard deviation of an absolute difference image."""
    hist = cv2.calcHist([difference], [0], None, [256], [0, 256]).ravel()
    cumulative = np.cumsum(hist)
    target = cumulative[-1] * quantile
    level = int(np.searchsorted(cumulative, target))
    # Interpolate inside the quantile's bin: integer grey levels would otherwise
    # round a clean camera's noise to exactly 0 or 1. Bin L holds the rounded
    # values [L - 0.5, L + 0.5), bin 0 only [0, 0.5).
    below = cumulative[level - 1] if level > 0 else 0.0
    inside = hist[level] if hist[level] > 0 else 1.0
    start, width = (level - 0.5, 1.0) if level > 0 else (0.0, 0.5)
    value = start + width * (target - below) / inside
    return max(0.0, float(value)) / half_normal_quantile(quantile)


class NoiseEstimator:
    """Running noise estimate, refreshed every few frames and smoothed over time."""

    def __init__(self, k: float = 4.0, floor: float = 10.0, ceiling: float = 60.0,
                 every: int = 4, smoothing: float = 0.2, quantile: float = 0.5) -> None:
        self.k = k
        self.floor = floor
        self.ceiling = ceiling
        self.every = every
        self.smoothing = smoothing
        self.quantile = quantile
        self.sigma: float | None = None
        self._count = 0

    def update(self, difference: GrayImage) -> None:
        self._count += 1
        if self.sigma is not None and self._count % self.every:
            return
        sigma = noise_sigma(difference, self.quantile)
        if self.sigma is None:
            self.sigma = sigma
        else:
            self.sigma += self.smoothing * (sigma - self.sigma)

    @property
    def threshold(self) -> float:
        """Grey-level threshold: k sigma, kept within [floor, ceiling]."""
        sigma = self.sigma if self.sigma is not None else 0.0
        return float(min(self.ceiling, max(self.floor, self.k * sigma)))

    def reset(self) -> None:
        self.sigma = None
        self._count = 0
