import numpy as np
import pytest

from app.vision.detections import LEFT, RIGHT, Box, Detection
from app.vision.kinematics import (
    Position,
    VelocityWindow,
    point_position,
    sighting_position,
    speed,
    step_length,
)


def fit_all(times: list[float], positions: list[Position]) -> tuple[float, float]:
    """The fit over all of these sightings."""
    window = VelocityWindow(most=max(1, len(times)))
    for time_s, position in zip(times, positions, strict=True):
        window.add(time_s, position)
    return window.velocity(times[-1])


def test_velocity_of_a_straight_track():
    times = [i / 10 for i in range(8)]
    points = [(5.0 + 3 * i, 10.0 - 4 * i) for i in range(8)]
    vx, vy = fit_all(times, [point_position(p) for p in points])
    assert (vx, vy) == pytest.approx((30.0, -40.0))
    assert speed((vx, vy)) == pytest.approx(50.0)


def test_one_jumping_centroid_does_not_tilt_the_fit():
    times = [i / 10 for i in range(9)]
    points = [(10.0 * i, 0.0) for i in range(9)]
    points[6] = (points[6][0] + 25.0, 0.0)  # a blob merged with a remnant for one frame
    assert fit_all(times, [point_position(p) for p in points])[0] == pytest.approx(100.0)


def test_too_few_samples_give_no_velocity():
    assert fit_all([0.0], [point_position((1.0, 1.0))]) == (0.0, 0.0)
    still = [point_position((0.0, 0.0)), point_position((5.0, 5.0))]
    assert fit_all([1.0, 1.0], still) == (0.0, 0.0)


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
    assert fit_all(times, centroids)[0] == pytest.approx(20.0)
    assert fit_all(times, [sighting_position(d) for d in sightings]) == pytest.approx((40.0, 0.0))


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
    velocity = fit_all([i / 10 for i in range(6)], [sighting_position(d) for d in wide])
    assert velocity == pytest.approx((0.0, 30.0))


def test_the_window_keeps_only_its_span_and_its_most_recent_sightings():
    window = VelocityWindow(span_s=0.5, most=4)
    for i in range(10):  # 100 px/s for a second...
        window.add(i / 10, point_position((10.0 * i, 0.0)))
    for i in range(10, 16):  # ...then 20 px/s.
        window.add(i / 10, point_position((90.0 + 2.0 * (i - 9), 0.0)))
    assert len(window) == 4
    assert window.velocity(1.5)[0] == pytest.approx(20.0)
    # Asked later, it forgets what is older than its span.
    assert window.velocity(1.85)[0] == pytest.approx(20.0)
    assert len(window) == 2
    assert window.velocity(2.1) == (0.0, 0.0)
    assert len(window) == 0


def brute_force_theil_sen(times: list[float], positions: list[Position]) -> tuple[float, float]:
    """Every pair's slope, per axis, from scratch."""
    slopes: tuple[list[float], list[float]] = ([], [])
    for i in range(len(times)):
        for j in range(i + 1, len(times)):
            if times[j] <= times[i]:
                continue
            for axis in (0, 1):
                start, end = positions[i][axis], positions[j][axis]
                cut_low, cut_high = start.cut_low or end.cut_low, start.cut_high or end.cut_high
                if cut_low and cut_high:
                    continue
                moved = (
                    end.high - start.high
                    if cut_low
                    else end.low - start.low
                    if cut_high
                    else end.centre - start.centre
                )
                slopes[axis].append(moved / (times[j] - times[i]))
    return (
        float(np.median(slopes[0])) if slopes[0] else 0.0,
        float(np.median(slopes[1])) if slopes[1] else 0.0,
    )


def test_the_windows_running_fit_is_the_fit_of_the_sightings_it_holds():
    rng = np.random.default_rng(7)
    window = VelocityWindow(span_s=0.6, most=12)
    times: list[float] = []
    positions: list[Position] = []
    time_s = 0.0
    for step in range(60):
        # Frames missed now and then, and a time repeated (a duplicated frame).
        time_s += float(rng.choice([0.04, 0.04, 0.08, 0.2, 0.0]))
        left = 5.0 * step + float(rng.normal(0, 2))
        sighting = Detection(
            Box(round(left), 40, 30, 20),
            (left + 15 + float(rng.normal(0, 1)), 50.0 + float(rng.normal(0, 1))),
            600.0,
            LEFT if rng.random() < 0.2 else 0,
        )
        window.add(time_s, sighting_position(sighting))
        times.append(time_s)
        positions.append(sighting_position(sighting))
        kept = [i for i, t in enumerate(times) if time_s - t <= 0.6][-12:]
        expected = brute_force_theil_sen([times[i] for i in kept], [positions[i] for i in kept])
        assert window.velocity(time_s) == expected  # The same arithmetic: bit for bit.


@pytest.mark.parametrize(("span_s", "most"), [(-1.0, 12), (float("nan"), 12), (0.6, 0)])
def test_a_window_that_could_hold_nothing_is_refused(span_s, most):
    with pytest.raises(ValueError):
        VelocityWindow(span_s, most)
