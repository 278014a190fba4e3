"""The paper's camera reference frame: from image pixels to metres on the ground.

A calibrated camera maps each object's ground contact point (the bottom
centre of its box) through a ground-plane homography, giving its position on
the ground in metres, its distance from the camera and its speed in m/s.
The homography comes either from four image points whose ground positions
are known, or from the camera's height, downward tilt and vertical field of
view (a pinhole camera with no roll).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from app.vision.detections import BOTTOM, LEFT, RIGHT, Detection
from app.vision.kinematics import VelocityWindow, point_position, speed

Point = tuple[float, float]
STALE_AFTER_S = 10.0

CUT_FOOTING = LEFT | RIGHT | BOTTOM
"""Frame edges that, cutting an object, move the middle of its box's bottom edge off its
foot: such sightings are left out of the ground speed (an object coming into view would
seem to walk at half its speed), which is unknown (None) until one is whole."""


@dataclass(frozen=True)
class GroundPlane:
    """Image -> ground homography, and where the camera stands on the ground (metres)."""

    homography: npt.NDArray[np.float64]
    camera_xy: Point = (0.0, 0.0)
    ground_side: float = 1.0
    """Sign of the homography's w on the ground side of the horizon."""

    @classmethod
    def from_points(
        cls,
        image_points: Sequence[Point],
        ground_points: Sequence[Point],
        camera_xy: Point = (0.0, 0.0),
    ) -> GroundPlane:
        """Four (or more) image points and their ground positions in metres."""
        if len(image_points) != len(ground_points) or len(image_points) < 4:
            raise ValueError("calibration needs at least four image points with ground positions")
        src = np.asarray(image_points, np.float64)
        dst = np.asarray(ground_points, np.float64)
        if _has_collinear_triple(src) or _has_collinear_triple(dst):
            raise ValueError("calibration points are degenerate: three of them lie on one line")
        homography, _ = cv2.findHomography(src, dst, 0)
        if homography is None or not np.all(np.isfinite(homography)):
            raise ValueError("calibration points give no homography")
        w = homography[2] @ np.array([src[0, 0], src[0, 1], 1.0])
        return cls(np.asarray(homography, np.float64), camera_xy, 1.0 if w >= 0 else -1.0)

    @classmethod
    def from_camera(
        cls, height_m: float, tilt_deg: float, vfov_deg: float, image_size: tuple[int, int]
    ) -> GroundPlane:
        """A camera ``height_m`` above the ground, tilted ``tilt_deg`` below the horizon.

        Ground axes: x to the camera's right, y straight ahead along the
        ground, origin under the camera. A ray through pixel (u, v) meets
        the ground at t * (dx, cos(tilt) - dy sin(tilt)) with
        t = height / (dy cos(tilt) + sin(tilt)), dx and dy being the pixel's
        offsets from the image centre over the focal length: a homography.
        """
        width, height = image_size
        if not all(map(math.isfinite, (height_m, tilt_deg, vfov_deg))):
            raise ValueError("camera height, tilt and field of view must be finite numbers")
        if height_m <= 0 or not 0 < vfov_deg < 180 or not 0 < tilt_deg <= 90:
            raise ValueError(
                "camera height must be > 0, tilt in (0, 90], field of view in (0, 180)"
            )
        focal = (height / 2.0) / math.tan(math.radians(vfov_deg) / 2.0)
        cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
        sin_t, cos_t = math.sin(math.radians(tilt_deg)), math.cos(math.radians(tilt_deg))
        homography = np.array(
            [
                [height_m, 0.0, -height_m * cx],
                [0.0, -height_m * sin_t, height_m * (focal * cos_t + cy * sin_t)],
                [0.0, cos_t, focal * sin_t - cy * cos_t],
            ]
        )
        return cls(homography)

    def to_ground(self, point: Point) -> Point | None:
        """Ground position of an image point; None at or above the horizon."""
        gx, gy, w = self.homography @ np.array([point[0], point[1], 1.0])
        if w * self.ground_side <= 1e-12:
            return None
        return (float(gx / w), float(gy / w))

    def range_m(self, ground_xy: Point) -> float:
        return math.dist(ground_xy, self.camera_xy)


def _has_collinear_triple(points: npt.NDArray[np.float64]) -> bool:
    """True when some three of the (first four) points lie on one line."""
    quad = points[:4]
    scale = float(np.ptp(quad, axis=0).max()) or 1.0
    for i, j, k in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):
        a, b = quad[j] - quad[i], quad[k] - quad[i]
        if abs(a[0] * b[1] - a[1] * b[0]) < 1e-6 * scale * scale:
            return True
    return False


class GroundTracker:
    """Adds ground position, range and smoothed ground speed to tracked detections."""

    def __init__(self, plane: GroundPlane, window_s: float = 0.6) -> None:
        self.plane = plane
        self.window_s = window_s
        self._history: dict[int, VelocityWindow] = {}

    def update(self, detections: list[Detection], time_s: float) -> list[Detection]:
        out = []
        for det in detections:
            ground = self.plane.to_ground(det.box.bottom_center)
            if ground is None or det.track_id is None:
                out.append(det)
                continue
            history = self._history.get(det.track_id)
            if history is None:
                history = self._history[det.track_id] = VelocityWindow(self.window_s)
            if not det.edges & CUT_FOOTING:
                history.add(time_s, point_position(ground))
            velocity = history.velocity(time_s)  # Forgets what is older than the window.
            ground_speed = speed(velocity) if history else None
            out.append(det.with_ground(ground, self.plane.range_m(ground), ground_speed))
        for track_id, history in list(self._history.items()):
            if not history or time_s - history.last_time > STALE_AFTER_S:
                del self._history[track_id]
        return out
