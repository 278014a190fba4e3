"""Feature extraction: blobs of the motion mask to boxes, centroids and areas."""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2

from app.vision.detections import BOTTOM, LEFT, RIGHT, TOP, Box, Detection
from app.vision.mask_box import motion_box
from app.vision.types import Mask


@dataclass(frozen=True)
class BlobExtractor:
    """Outer contours of the mask, kept when their area reaches ``min_area``.

    ``min_area`` is in pixels of the input frame; ``scale`` maps mask pixels
    back to input pixels when detection ran on a smaller frame, whose boxes
    stay inside the input's ``frame_size`` (the smaller frame's side is
    rounded, so its last pixel may reach past the input's). Contours are
    used rather than ``connectedComponentsWithStats``, which measured several
    times slower at 640x480 (bench/bench_pipeline.py prints both).
    """

    min_area: float = 100.0

    def __call__(
        self, mask: Mask, scale: float = 1.0, frame_size: tuple[int, int] | None = None
    ) -> list[Detection]:
        # Contours are sought in the box of the mask's pixels only, with a pixel of
        # background around them (the same contours, for less of the frame to scan).
        box = motion_box(mask, 1)
        if box is None:
            return []
        rows, cols = box
        contours, _ = cv2.findContours(
            mask[box], cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE, offset=(cols.start, rows.start)
        )
        area_scale = scale * scale
        height, width = mask.shape[:2]
        limits = frame_size or (math.ceil(width * scale), math.ceil(height * scale))
        detections = []
        for contour in contours:
            x, y, w, h = cv2.boundingRect(contour)
            if w * h * area_scale < self.min_area:
                continue  # Not even its whole box would be large enough.
            moments = cv2.moments(contour)
            # A contour's polygon area undercounts thin blobs; the filled box
            # bounds it from above. Pixel count sits between: take the mask's.
            pixels = float(cv2.countNonZero(mask[y : y + h, x : x + w]))
            area = pixels * area_scale
            if area < self.min_area:
                continue
            if moments["m00"] > 0:
                cx, cy = moments["m10"] / moments["m00"], moments["m01"] / moments["m00"]
            else:
                cx, cy = x + (w - 1) / 2.0, y + (h - 1) / 2.0
            edges = (
                (LEFT if x == 0 else 0)
                | (RIGHT if x + w == width else 0)
                | (TOP if y == 0 else 0)
                | (BOTTOM if y + h == height else 0)
            )
            detections.append(_scaled(x, y, w, h, cx, cy, area, edges, scale, limits))
        detections.sort(key=lambda d: (d.box.y, d.box.x))
        return detections


def _scaled(
    x: int,
    y: int,
    w: int,
    h: int,
    cx: float,
    cy: float,
    area: float,
    edges: int,
    scale: float,
    limits: tuple[int, int],
) -> Detection:
    if scale == 1.0:
        return Detection(Box(x, y, w, h), (cx, cy), area, edges)
    # Pixel centres: mask pixel i covers input pixels [i*s, (i+1)*s).
    # math, not NumPy: a NumPy call on a plain number costs more than the arithmetic.
    x0, y0 = math.floor(x * scale), math.floor(y * scale)
    x1 = min(math.ceil((x + w) * scale), limits[0])
    y1 = min(math.ceil((y + h) * scale), limits[1])
    centroid = ((cx + 0.5) * scale - 0.5, (cy + 0.5) * scale - 0.5)
    return Detection(Box(x0, y0, x1 - x0, y1 - y0), centroid, area, edges)
