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
from collections import deque
from dataclasses import dataclass, field
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


class VelocityWindow:
    """Velocity fitted over the last ``span_s`` seconds of sightings (``most`` at most):
    the median of the slopes between every pair of them (Theil-Sen), per axis.

    Fitting a line over a window averages out the jitter of blob centroids
    that a frame-to-frame difference (distance x frame rate) passes straight
    through. Least squares would do that too, but a blob that splits, merges
    or drags a remnant along jumps its centroid for a frame or a few, and one
    such jump tilts a least-squares line; the median of pairwise slopes stays
    put until nearly three samples in ten are off.

    The slopes are kept pair by pair: a new sighting adds its slopes to those
    before it, and one that leaves the window takes its own with it, so a
    frame computes a dozen slopes rather than all 66 pairs of a full window.
    Sightings come in time order (the oldest leave first).
    Plain Python: at this size NumPy's per-call overhead costs more than the
    arithmetic, and more still on a camera whose code has gone cold between
    frames.
    """

    def __init__(self, span_s: float = math.inf, most: int = 12) -> None:
        if most < 1:
            raise ValueError(f"a window holds at least one sighting, not {most}")
        if not span_s >= 0:  # NaN too.
            raise ValueError(f"a window spans 0 seconds or more, not {span_s}")
        self.span_s = span_s
        self.most = most
        self._samples: deque[_Sample] = deque()

    def __len__(self) -> int:
        return len(self._samples)

    @property
    def last_time(self) -> float:
        return self._samples[-1].time_s

    @property
    def last_position(self) -> Position:
        return self._samples[-1].position

    def add(self, time_s: float, position: Position) -> None:
        while len(self._samples) >= self.most:
            self._samples.popleft()
        self._forget_before(time_s)
        for sample in self._samples:
            elapsed = time_s - sample.time_s
            if elapsed <= 0.0:
                continue
            dx = displacement(sample.position[0], position[0])
            dy = displacement(sample.position[1], position[1])
            if dx is not None:
                sample.slopes_x.append(dx / elapsed)
            if dy is not None:
                sample.slopes_y.append(dy / elapsed)
        self._samples.append(_Sample(time_s, position))

    def velocity(self, now_s: float) -> tuple[float, float]:
        """The fit over the sightings within ``span_s`` of ``now_s`` ((0, 0) for fewer
        than two)."""
        self._forget_before(now_s)
        return (
            _median([slope for sample in self._samples for slope in sample.slopes_x]),
            _median([slope for sample in self._samples for slope in sample.slopes_y]),
        )

    def _forget_before(self, now_s: float) -> None:
        while self._samples and now_s - self._samples[0].time_s > self.span_s:
            self._samples.popleft()


@dataclass(slots=True)
class _Sample:
    time_s: float
    position: Position
    slopes_x: list[float] = field(default_factory=list)
    """Slopes to each later sighting in the window."""
    slopes_y: list[float] = field(default_factory=list)


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
