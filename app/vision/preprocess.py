"""The paper's pre-processing stages: noise removal, grayscale, contrast enhancement.

Each stage is a small callable (array in, array out) so the pipeline can swap,
test and time them one by one.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

from app.vision.compiled import compiled
from app.vision.types import GrayImage, Image

DenoiseMethod = Literal["none", "median", "mean", "gaussian"]
EnhanceMethod = Literal["none", "equalize", "clahe"]
DENOISE_METHODS: tuple[DenoiseMethod, ...] = ("none", "median", "mean", "gaussian")
ENHANCE_METHODS: tuple[EnhanceMethod, ...] = ("none", "equalize", "clahe")


def to_gray(frame: Image) -> GrayImage:
    """BGR (or already grey) frame to an 8-bit grey image."""
    if frame.ndim == 2:
        return frame
    if frame.shape[2] == 4:
        return cv2.cvtColor(frame, cv2.COLOR_BGRA2GRAY)
    return cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)


@dataclass(frozen=True)
class Denoise:
    """Noise removal: median, mean (box) or Gaussian filter with an odd kernel 1..7."""

    method: DenoiseMethod = "gaussian"
    kernel: int = 3

    def __post_init__(self) -> None:
        if self.method not in DENOISE_METHODS:
            raise ValueError(
                f"unknown denoise method {self.method!r}; choose from {DENOISE_METHODS}"
            )
        if self.kernel not in (1, 3, 5, 7):
            raise ValueError(f"denoise kernel must be 1, 3, 5 or 7, not {self.kernel}")

    def __call__(self, image: GrayImage) -> GrayImage:
        k = self.kernel
        if self.method == "none" or k == 1:
            return image
        if self.method == "median":
            return cv2.medianBlur(image, k)
        if self.method == "mean":
            return cv2.blur(image, (k, k))
        if k == 3 and image.ndim == 2 and image.dtype == np.uint8 and min(image.shape) >= 2:
            # The default, on every frame: OpenCV's result in about half its time (one
            # small compiled loop, which costs less to wake than OpenCV's call).
            smoothed = np.empty_like(image)
            gaussian_3x3(np.ascontiguousarray(image), smoothed)
            return smoothed
        return cv2.GaussianBlur(image, (k, k), 0)


@compiled
def gaussian_3x3(image: GrayImage, out: GrayImage) -> None:
    """``cv2.GaussianBlur(image, (3, 3), 0)`` of an 8-bit image at least 2x2, into ``out``:
    the kernel [1, 2, 1] / 4 down and across, rounded half up, the edges reflected as
    OpenCV's default border reflects them (-1 is 1)."""
    rows, cols = image.shape
    across = np.empty(cols, np.uint16)
    for y in range(rows):
        above = image[y - 1 if y > 0 else 1]
        below = image[y + 1 if y < rows - 1 else rows - 2]
        row = image[y]
        for x in range(cols):
            across[x] = np.uint16(above[x]) + np.uint16(2) * row[x] + below[x]
        smoothed = out[y]
        smoothed[0] = (np.uint16(2) * (across[0] + across[1]) + 8) >> 4
        for x in range(1, cols - 1):
            smoothed[x] = (across[x - 1] + np.uint16(2) * across[x] + across[x + 1] + 8) >> 4
        smoothed[cols - 1] = (np.uint16(2) * (across[cols - 2] + across[cols - 1]) + 8) >> 4


@dataclass(frozen=True)
class Enhance:
    """Contrast enhancement: the paper's histogram equalisation, or CLAHE.

    Equalising each frame on its own shifts grey levels when the content
    changes, so it is off by default; it helps when a fixed sensitivity is
    set on a dark scene.
    """

    method: EnhanceMethod = "none"

    def __post_init__(self) -> None:
        if self.method not in ENHANCE_METHODS:
            raise ValueError(f"unknown enhancement {self.method!r}; choose from {ENHANCE_METHODS}")

    def __call__(self, image: GrayImage) -> GrayImage:
        if self.method == "equalize":
            return cv2.equalizeHist(image)
        if self.method == "clahe":
            return _clahe().apply(image)
        return image


def _clahe() -> cv2.CLAHE:
    return cv2.createCLAHE(clipLimit=2.0, tileGridSize=(8, 8))


@dataclass(frozen=True)
class Downscale:
    """Shrink frames wider than ``max_width`` for detection; boxes are mapped back.

    Motion is found as well at 320 pixels across as at full size, for a
    fraction of the work.
    """

    max_width: int = 320

    def scale_for(self, width: int) -> float:
        """Factor from detection pixels back to input pixels (>= 1)."""
        if self.max_width <= 0 or width <= self.max_width:
            return 1.0
        return width / self.max_width

    def __call__(self, image: GrayImage) -> GrayImage:
        scale = self.scale_for(image.shape[1])
        if scale == 1.0:
            return image
        size = (round(image.shape[1] / scale), round(image.shape[0] / scale))
        return cv2.resize(image, size, interpolation=cv2.INTER_AREA)


def to_size(image: Image, size: tuple[int, int]) -> Image:
    """An image at ``size`` (width, height): a detection-resolution mask back at input size.

    Nearest neighbour, so a binary mask stays binary.
    """
    if (image.shape[1], image.shape[0]) == size:
        return image
    return cv2.resize(image, size, interpolation=cv2.INTER_NEAREST)


def as_uint8(image: np.ndarray) -> GrayImage:
    """Clip and convert any numeric image to 8 bits."""
    if image.dtype == np.uint8:
        return image
    return np.clip(image, 0, 255).astype(np.uint8)
