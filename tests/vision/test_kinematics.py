import pytest

from app.vision.detections import LEFT, RIGHT, Box, Detection
from app.vision.kinematics import (
    fit_velocity,
    point_position,
    sighting_position,
    speed,
    step_length,
)


def test_velocity_of_a_straight_track():
    times = [i / 10 for i in range(8)]
    points = [(5.0 + 3 * i, 10.0 - 4 * i) for i in range(8)]
    vx, vy = fit_velocity(times, [point_position(p) for p in points])
    assert (vx, vy) == pytest.approx((30.0, -40.0))
    assert speed((vx, vy)) == pytest.approx(50.0)


def test_one_jumping_centroid_does_not_tilt_the_fit():
    times = [i / 10 for i in range(9)]
    points = [(10.0 * i, 0.0) for i in range(9)]
    points[6] = (points[6][0] + 25.0, 0.0)  # a blob merged with a remnant for one frame
    assert fit_velocity(times, [point_position(p) for p in points])[0] == pytest.approx(100.0)


def test_too_few_samples_give_no_velocity():
    assert fit_velocity([0.0], [point_position((1.0, 1.0))]) == (0.0, 0.0)
    still = [point_position((0.0, 0.0)), point_position((5.0, 5.0))]
    assert fit_velocity([1.0, 1.0], still) == (0.0, 0.0)


def entering_from_the_left(step: int, speed_px: float = 4.0, width: int = 40) -> Detection:
    """An object ``width`` wide whose right side is ``speed_px`` per frame into the view:
    until it is all in, the frame's left edge cuts it and its visible part grows."""
    right = speed_px * (step + 1)
    left = max(0.0, right - width)
    box = Box(round(left), 50, round(right - left), 20)
    edges = LEFT if left == 0.0 else 0
    return Detection(box, ((left + right) / 2, 60.0), box.area, edges)


def test_an_object_entering_the_view_moves_at_its_own_speed_not_its_visible_parts():
    times = [i / 10 for i in range(8)]
    sightings = [entering_from_the_left(i) for i in range(8)]  # 4 px a frame at 10 fps
    centroids = [point_position(d.centroid) for d in sightings]
    # The centre of what shows moves at half speed while the edge hides the rest.
    assert fit_velocity(times, centroids)[0] == pytest.approx(20.0)
    assert fit_velocity(times, [sighting_position(d) for d in sightings]) == pytest.approx(
        (40.0, 0.0)
    )


def test_a_step_across_the_moment_an_object_is_all_in_view_is_its_whole_step():
    # Cut by the edge, then clear of it two frames later: the object moved 8 px, the
    # centre of what showed 6.
    before, after = entering_from_the_left(8), entering_from_the_left(10)
    assert before.edges == LEFT and after.edges == 0
    assert after.centroid[0] - before.centroid[0] == pytest.approx(6.0)
    assert step_length(sighting_position(before), sighting_position(after)) == pytest.approx(8.0)


def test_an_object_cut_on_both_sides_gives_no_speed_along_that_axis():
    wide = [
        Detection(Box(0, 10 + 3 * i, 320, 20), (160.0, 20.0 + 3 * i), 6400.0, LEFT | RIGHT)
        for i in range(6)
    ]
    velocity = fit_velocity([i / 10 for i in range(6)], [sighting_position(d) for d in wide])
    assert velocity == pytest.approx((0.0, 30.0))
