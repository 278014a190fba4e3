"""Velocity from a short history of positions, fitted robustly."""

from __future__ import annotations

from collections.abc import Sequence

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
    if len(times) < 2:
        return (0.0, 0.0)
    t = np.asarray(times, dtype=np.float64)
    xy = np.asarray(points, dtype=np.float64)
    first, second = np.triu_indices(len(t), 1)
    elapsed = t[second] - t[first]
    usable = elapsed > 0.0
    if not usable.any():
        return (0.0, 0.0)
    slopes = (xy[second] - xy[first])[usable] / elapsed[usable, None]
    median = np.median(slopes, axis=0)
    return (float(median[0]), float(median[1]))


def speed(velocity: tuple[float, float]) -> float:
    return float(np.hypot(*velocity))
