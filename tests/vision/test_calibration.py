import math

import pytest

from app.vision.calibration import GroundPlane, GroundTracker
from app.vision.detections import LEFT, Box, Detection


def test_homography_from_four_points_maps_them_exactly():
    image = [(100, 400), (540, 400), (400, 200), (240, 200)]
    ground = [(-2.0, 5.0), (2.0, 5.0), (2.0, 20.0), (-2.0, 20.0)]
    plane = GroundPlane.from_points(image, ground)
    for p, g in zip(image, ground, strict=True):
        assert plane.to_ground(p) == pytest.approx(g, abs=1e-6)


def test_degenerate_points_are_refused():
    with pytest.raises(ValueError):
        GroundPlane.from_points([(0, 0), (1, 1), (2, 2), (3, 3)], [(0, 0), (1, 1), (2, 2), (3, 3)])
    with pytest.raises(ValueError, match="four"):
        GroundPlane.from_points([(0, 0)], [(0, 0)])


def test_camera_model_distance_along_optical_axis():
    # Camera 5 m up, tilted 30 deg down: the image centre sees the ground 5/tan(30) m ahead.
    plane = GroundPlane.from_camera(5.0, 30.0, 45.0, (641, 481))
    x, y = plane.to_ground((320, 240))
    assert x == pytest.approx(0.0, abs=1e-9)
    assert y == pytest.approx(5.0 / math.tan(math.radians(30)), rel=1e-6)
    assert plane.range_m((x, y)) == pytest.approx(y)


def test_points_above_the_horizon_have_no_ground_position():
    plane = GroundPlane.from_camera(5.0, 10.0, 60.0, (640, 480))
    assert plane.to_ground((320, 0)) is None


def test_ground_speed_in_metres_per_second():
    # Looking straight down from 10 m with a 90 deg vertical field of view on a 200 px
    # tall image: 100 px = 10 m, so 1 px = 0.1 m.
    plane = GroundPlane.from_camera(10.0, 90.0, 90.0, (201, 201))
    tracker = GroundTracker(plane)
    out = []
    for i in range(10):
        x = 50.0 + 5 * i  # 5 px per frame at 10 fps = 50 px/s = 5 m/s
        d = Detection(Box(round(x) - 5, 95, 10, 10), (x, 100.0), 100.0, track_id=1)
        out = tracker.update([d], i / 10)
    assert out[0].speed_m_s == pytest.approx(5.0, rel=0.02)
    assert out[0].range_m is not None


def test_ground_speed_leaves_out_sightings_the_frame_edge_cuts():
    # The same straight-down camera; an object 20 px wide comes in at the left edge,
    # 5 px a frame at 10 fps (5 m/s): while the edge cuts it, the middle of its
    # box's bottom moves at half that.
    plane = GroundPlane.from_camera(10.0, 90.0, 90.0, (201, 201))
    tracker = GroundTracker(plane)
    speeds = []
    for i in range(12):
        right = 5.0 * (i + 1)
        left = max(0.0, right - 20.0)
        box = Box(round(left), 95, round(right - left), 10)
        d = Detection(box, box.center, float(box.area), LEFT if left == 0 else 0, track_id=1)
        (out,) = tracker.update([d], i / 10)
        speeds.append(out.speed_m_s)
    assert speeds[:4] == [None] * 4  # cut: no whole sighting yet
    assert speeds[-1] == pytest.approx(5.0, rel=0.02)
