"""Ignore zones: parts of the picture where motion does not count (a road beside the
garden, a flag, a clock on the wall), the way Motion's and Frigate's motion masks work.

Polygons are given in fractions of the frame's width and height (0..1), so one
mask fits every resolution the camera or the detector runs at.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from app.vision.types import Mask

Point = tuple[float, float]
Polygon = tuple[Point, ...]


def as_polygons(value: Sequence[Sequence[Sequence[float]]]) -> tuple[Polygon, ...]:
    """Validate polygons given as lists of [x, y] fractions; ValueError says what is wrong."""
    polygons = []
    for polygon in value:
        if len(polygon) < 3:
            raise ValueError("an ignore zone needs at least three points")
        points = []
        for point in polygon:
            if len(point) != 2:
                raise ValueError(f"a point is [x, y], not {list(point)!r}")
            x, y = float(point[0]), float(point[1])
            if not (0.0 <= x <= 1.0 and 0.0 <= y <= 1.0):
                raise ValueError(f"zone points are fractions of the frame (0..1), not {[x, y]}")
            points.append((x, y))
        polygons.append(tuple(points))
    return tuple(polygons)


@dataclass(frozen=True)
class IgnoreZones:
    polygons: tuple[Polygon, ...] = ()
    _keep: dict[tuple[int, int], Mask] = field(default_factory=dict, compare=False, repr=False)
    _watched: dict[tuple[int, int], int] = field(default_factory=dict, compare=False, repr=False)

    def __call__(self, mask: Mask) -> Mask:
        """The motion mask with everything inside the zones cleared."""
        if not self.polygons:
            return mask
        return cv2.bitwise_and(mask, self._keep_mask(mask.shape[1], mask.shape[0]))

    def watched(self, width: int, height: int) -> int:
        """Pixels of a ``width`` x ``height`` mask outside the zones."""
        if not self.polygons:
            return width * height
        size = (width, height)
        if size not in self._watched:  # Counted once per size: it is asked every frame.
            self._watched[size] = cv2.countNonZero(self._keep_mask(width, height))
        return self._watched[size]

    def _keep_mask(self, width: int, height: int) -> Mask:
        keep = self._keep.get((width, height))
        if keep is None:
            keep = np.full((height, width), 255, np.uint8)
            scale = np.array([width, height], np.float64)
            outlines = [np.round(np.array(p) * scale).astype(np.int32) for p in self.polygons]
            cv2.fillPoly(keep, outlines, 0)
            self._keep[(width, height)] = keep
        return keep
