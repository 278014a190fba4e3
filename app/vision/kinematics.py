"""Velocity from a short history of positions, smoothed by a least-squares fit."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def fit_velocity(
    times: Sequence[float], points: Sequence[tuple[float, float]]
) -> tuple[float, float]:
    """Slope of position over time (units per second), fitted to every sample.

    A straight-line fit over a window averages out the jitter of blob
    centroids that a frame-to-frame difference (distance x frame rate) would
    pass straight through.
    """
    if len(times) < 2:
        return (0.0, 0.0)
    t = np.asarray(times, dtype=np.float64)
    xy = np.asarray(points, dtype=np.float64)
    t = t - t.mean()
    denominator = float(np.dot(t, t))
    if denominator <= 0.0:
        return (0.0, 0.0)
    slope = t @ (xy - xy.mean(axis=0)) / denominator
    return (float(slope[0]), float(slope[1]))


def speed(velocity: tuple[float, float]) -> float:
    return float(np.hypot(*velocity))
