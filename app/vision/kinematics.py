"""Velocity from a short history of positions, fitted robustly.

A position is given per axis (``AxisPosition``): the object's centre and the
two sides of its box, and whether the frame's edge cuts it on either side.
An object that enters or leaves the picture shows only part of itself: the
centre of what shows moves at half the object's speed, but the side of the
box away from the frame's edge moves with the object. So a step between two
sightings is measured by the centre when neither is cut on that axis, and by
the whole side when one is.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

from app.vision.detections import BOTTOM, LEFT, RIGHT, TOP, Detection


class AxisPosition(NamedTuple):
    centre: float
    low: float
    """The box's side nearer 0 (left or top)."""
    high: float
    cut_low: bool = False
    """Whether the frame's edge cuts the object on its low side (it is not all in view)."""
    cut_high: bool = False


Position = tuple[AxisPosition, AxisPosition]
"""(x, y)."""


def point_position(point: tuple[float, float]) -> Position:
    """A point that is all there is to see (a ground position, a centroid without a box)."""
    x, y = point
    return (AxisPosition(x, x, x), AxisPosition(y, y, y))


def sighting_position(detection: Detection) -> Position:
    box, edges = detection.box, detection.edges
    return (
        AxisPosition(
            detection.centroid[0],
            box.x,
            box.x + box.w,
            bool(edges & LEFT),
            bool(edges & RIGHT),
        ),
        AxisPosition(
            detection.centroid[1],
            box.y,
            box.y + box.h,
            bool(edges & TOP),
            bool(edges & BOTTOM),
        ),
    )


def displacement(start: AxisPosition, end: AxisPosition) -> float | None:
    """How far the object moved along one axis; None when the frame cuts both its sides
    (an object wider than the view: nothing of it shows where it is)."""
    cut_low = start.cut_low or end.cut_low
    cut_high = start.cut_high or end.cut_high
    if cut_low and cut_high:
        return None
    if cut_low:
        return end.high - start.high
    if cut_high:
        return end.low - start.low
    return end.centre - start.centre


def step_length(start: Position, end: Position) -> float:
    """The distance between two sightings (an axis that cannot tell counts as still)."""
    dx = displacement(start[0], end[0])
    dy = displacement(start[1], end[1])
    return math.hypot(dx or 0.0, dy or 0.0)


def fit_velocity(times: Sequence[float], positions: Sequence[Position]) -> tuple[float, float]:
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
    centres = [(x.centre, y.centre) for x, y in positions]
    cut = [x.cut_low or x.cut_high or y.cut_low or y.cut_high for x, y in positions]
    for i in range(len(times) - 1):
        t0, (x0, y0) = times[i], centres[i]
        for j in range(i + 1, len(times)):
            elapsed = times[j] - t0
            if elapsed <= 0.0:
                continue
            if cut[i] or cut[j]:
                dx = displacement(positions[i][0], positions[j][0])
                dy = displacement(positions[i][1], positions[j][1])
            else:  # The usual pair, both whole: their centres.
                x1, y1 = centres[j]
                dx, dy = x1 - x0, y1 - y0
            if dx is not None:
                slopes_x.append(dx / elapsed)
            if dy is not None:
                slopes_y.append(dy / elapsed)
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
