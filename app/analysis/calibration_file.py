"""Read a camera calibration (`vigil analyze --calibration FILE`), see docs/calibration.md.

Either four or more image points with their ground positions in metres::

    {"image_points": [[u, v], ...], "ground_points": [[x, y], ...], "camera_xy": [x, y]}

or the camera's mounting::

    {"camera_height_m": 6.0, "tilt_deg": 30, "vertical_fov_deg": 45}
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from app.vision.calibration import GroundPlane

MAX_COORDINATE = 1e7
"""Pixels and metres past this are typos, and overflow the homography into infinities."""
MAX_HEIGHT_M = 10_000.0
MIN_FOV_DEG = 0.1
"""A narrower field of view puts the focal length, and ground positions, out of range."""


class CalibrationError(ValueError):
    """The calibration file cannot be used; the message says why."""


def load_calibration(path: Path, image_size: tuple[int, int]) -> GroundPlane:
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise CalibrationError(f"calibration file not found: {path}") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CalibrationError(f"cannot read calibration {path}: {exc}") from None
    if not isinstance(data, dict):
        raise CalibrationError(f"{path}: expected a JSON object")
    try:
        if "image_points" in data:
            return GroundPlane.from_points(
                [_point(p) for p in _list(data["image_points"])],
                [_point(p) for p in _list(data["ground_points"])],
                _point(data.get("camera_xy", (0.0, 0.0))),
            )
        height_m, fov = float(data["camera_height_m"]), float(data["vertical_fov_deg"])
        if not height_m <= MAX_HEIGHT_M:
            raise ValueError(f"camera height must be at most {MAX_HEIGHT_M:g} m")
        if not fov >= MIN_FOV_DEG:
            raise ValueError(f"field of view must be at least {MIN_FOV_DEG:g} degrees")
        return GroundPlane.from_camera(height_m, float(data["tilt_deg"]), fov, image_size)
    except KeyError as exc:
        raise CalibrationError(
            f"{path}: missing {exc.args[0]!r} (see docs/calibration.md)"
        ) from None
    except (TypeError, ValueError) as exc:
        raise CalibrationError(f"{path}: {exc}") from None


def _list(value: object) -> list[object]:
    if not isinstance(value, list):
        raise ValueError(f"expected a list of [x, y] points, not {value!r}")
    return value


def _point(value: object) -> tuple[float, float]:
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise ValueError(f"a point is [x, y], not {value!r}")
    point = (float(value[0]), float(value[1]))
    if not all(math.isfinite(v) and abs(v) <= MAX_COORDINATE for v in point):
        raise ValueError(f"a point needs numbers within ±{MAX_COORDINATE:g}, not {value!r}")
    return point
