"""Velocity from a short history of positions, fitted robustly."""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np


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
    count = len(times)
    if count < 2:
        return (0.0, 0.0)
    t = np.asarray(times, dtype=np.float64)
    xy = np.asarray(points, dtype=np.float64)
    first, second = _pairs(count)
    elapsed = t[second] - t[first]
    slopes = xy[second] - xy[first]
    usable = elapsed > 0.0
    if not usable.all():
        if not usable.any():
            return (0.0, 0.0)
        slopes, elapsed = slopes[usable], elapsed[usable]
    slopes /= elapsed[:, None]
    # A sort and the middle row: np.median costs more than the fit on arrays this small.
    slopes.sort(axis=0)
    middle = len(slopes) // 2
    median = slopes[middle] if len(slopes) % 2 else (slopes[middle - 1] + slopes[middle]) / 2
    return (float(median[0]), float(median[1]))


@lru_cache(maxsize=64)
def _pairs(count: int) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i < j) of ``count`` samples."""
    first, second = np.triu_indices(count, 1)
    return first, second


def speed(velocity: tuple[float, float]) -> float:
    return float(np.hypot(*velocity))
