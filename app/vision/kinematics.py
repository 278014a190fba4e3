"""Velocity from a short history of positions, fitted robustly."""

from __future__ import annotations

import math
from collections.abc import Sequence


def fit_velocity(
    times: Sequence[float], points: Sequence[tuple[float, float]]
) -> tuple[float, float]:
    """Median of the slopes between every pair of samples (Theil-Sen), per axis.

    Fitting a line over a window averages out the jitter of blob centroids
    that a frame-to-frame difference (distance x frame rate) passes straight
    through. Least squares would do that too, but a blob that splits, merges
    or drags a remnant along jumps its centroid for a frame or a few, and one
    such jump tilts a least-squares line; the median of pairwise slopes stays
    put until nearly three samples in ten are off.
    """
    # Plain Python: a track has at most a dozen samples (66 pairs), where NumPy's
    # per-call overhead costs more than the arithmetic, and more still on a camera
    # whose code has gone cold between frames.
    slopes_x: list[float] = []
    slopes_y: list[float] = []
    for i in range(len(times) - 1):
        t0, (x0, y0) = times[i], points[i]
        for j in range(i + 1, len(times)):
            elapsed = times[j] - t0
            if elapsed > 0.0:
                x1, y1 = points[j]
                slopes_x.append((x1 - x0) / elapsed)
                slopes_y.append((y1 - y0) / elapsed)
    return (_median(slopes_x), _median(slopes_y))


def _median(values: list[float]) -> float:
    if not values:
        return 0.0
    values.sort()
    middle = len(values) // 2
    if len(values) % 2:
        return float(values[middle])
    return float((values[middle - 1] + values[middle]) / 2)


def speed(velocity: tuple[float, float]) -> float:
    return math.hypot(*velocity)
