"""Read a camera calibration (`vigil analyze --calibration FILE`), see docs/calibration.md.

Either four or more image points with their ground positions in metres::

    {"image_points": [[u, v], ...], "ground_points": [[x, y], ...], "camera_xy": [x, y]}

or the camera's mounting::

    {"camera_height_m": 6.0, "tilt_deg": 30, "vertical_fov_deg": 45}
"""

from __future__ import annotations

import json
from pathlib import Path

from app.vision.calibration import GroundPlane


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
            camera = tuple(float(v) for v in data.get("camera_xy", (0.0, 0.0)))
            if len(camera) != 2:
                raise ValueError("camera_xy needs two numbers")
            return GroundPlane.from_points(
                [_point(p) for p in data["image_points"]],
                [_point(p) for p in data["ground_points"]],
                (camera[0], camera[1]),
            )
        return GroundPlane.from_camera(
            float(data["camera_height_m"]),
            float(data["tilt_deg"]),
            float(data["vertical_fov_deg"]),
            image_size,
        )
    except KeyError as exc:
        raise CalibrationError(
            f"{path}: missing {exc.args[0]!r} (see docs/calibration.md)"
        ) from None
    except (TypeError, ValueError) as exc:
        raise CalibrationError(f"{path}: {exc}") from None


def _point(value: object) -> tuple[float, float]:
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise ValueError(f"a point is [x, y], not {value!r}")
    return (float(value[0]), float(value[1]))
