"""Grey-level histogram and the frame statistics the paper reports."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from app.vision.types import GrayImage, Image


@dataclass(frozen=True, slots=True)
class GreyStats:
    """Mean and standard deviation of a frame's grey levels."""

    mean: float
    std: float


def grey_stats(gray: GrayImage) -> GreyStats:
    mean, std = cv2.meanStdDev(gray)
    return GreyStats(mean=float(mean[0, 0]), std=float(std[0, 0]))


def grey_histogram(gray: GrayImage) -> npt.NDArray[np.int64]:
    """256-bin histogram: counts of each grey level 0..255."""
    hist = cv2.calcHist([gray], [0], None, [256], [0, 256])
    return hist.ravel().astype(np.int64)


def render_histogram(
    hist: npt.NDArray[np.int64], stats: GreyStats, width: int = 256, height: int = 120
) -> Image:
    """Draw a histogram as a small BGR picture (for the live histogram stream)."""
    canvas = np.full((height, width, 3), 24, np.uint8)
    peak = max(int(hist.max()), 1)
    plot_h = height - 16
    xs = np.linspace(0, width, 257).astype(np.int32)
    for level in range(256):
        bar = round(plot_h * hist[level] / peak)
        if bar:
            shade = (level, level, level)
            cv2.rectangle(
                canvas, (int(xs[level]), plot_h - bar), (int(xs[level + 1]) - 1, plot_h), shade, -1
            )
    cv2.rectangle(canvas, (0, 0), (width - 1, plot_h), (90, 90, 90), 1)
    mean_x = round(stats.mean * width / 256)
    cv2.line(canvas, (mean_x, 0), (mean_x, plot_h), (0, 0, 255), 1)
    label = f"mean {stats.mean:5.1f}  std {stats.std:5.1f}"
    cv2.putText(canvas, label, (4, height - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (230, 230, 230), 1)
    return canvas
