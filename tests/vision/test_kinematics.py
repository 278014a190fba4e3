import pytest

from app.vision.kinematics import fit_velocity, speed


def test_velocity_of_a_straight_track():
    times = [i / 10 for i in range(8)]
    points = [(5.0 + 3 * i, 10.0 - 4 * i) for i in range(8)]
    vx, vy = fit_velocity(times, points)
    assert (vx, vy) == pytest.approx((30.0, -40.0))
    assert speed((vx, vy)) == pytest.approx(50.0)


def test_one_jumping_centroid_does_not_tilt_the_fit():
    times = [i / 10 for i in range(9)]
    points = [(10.0 * i, 0.0) for i in range(9)]
    points[6] = (points[6][0] + 25.0, 0.0)  # a blob merged with a remnant for one frame
    assert fit_velocity(times, points)[0] == pytest.approx(100.0)


def test_too_few_samples_give_no_velocity():
    assert fit_velocity([0.0], [(1.0, 1.0)]) == (0.0, 0.0)
    assert fit_velocity([1.0, 1.0], [(0.0, 0.0), (5.0, 5.0)]) == (0.0, 0.0)
