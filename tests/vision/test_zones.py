import numpy as np
import pytest

from app.sources.synthetic import MovingObject, Scene
from app.vision.pipeline import Pipeline, PipelineConfig
from app.vision.zones import IgnoreZones, as_polygons

LEFT_HALF = ((0.0, 0.0), (0.5, 0.0), (0.5, 1.0), (0.0, 1.0))


def test_motion_inside_a_zone_is_cleared_at_any_resolution():
    zones = IgnoreZones((LEFT_HALF,))
    for width, height in ((320, 240), (640, 480)):
        mask = np.full((height, width), 255, np.uint8)
        out = zones(mask)
        assert not out[:, : width // 2 - 1].any()
        assert out[:, width // 2 + 1 :].all()


def test_no_zones_leave_the_mask_alone():
    mask = np.full((10, 10), 255, np.uint8)
    assert IgnoreZones()(mask) is mask


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ([[[0, 0], [1, 0]]], "three points"),
        ([[[0, 0], [2, 0], [1, 1]]], "fractions"),
        ([[[0, 0, 0], [1, 0], [1, 1]]], "a point is"),
    ],
)
def test_bad_zones_are_refused(value, message):
    with pytest.raises(ValueError, match=message):
        as_polygons(value)


def test_a_walker_in_an_ignored_zone_raises_nothing_until_it_leaves():
    scene = Scene(
        name="zone", frames=60,
        objects=(MovingObject((10, 100), (90.0, 0.0), (26, 40), 220, first_frame=3),),
    )  # fmt: skip
    pipeline = Pipeline(PipelineConfig(ignore_zones=(LEFT_HALF,)), fps=scene.fps)
    found = {i: pipeline.process(scene.frame(i)).detections for i in range(scene.frames)}
    truth_x = {i: scene.truth(i)[0].box.x for i in found if scene.truth(i)}
    assert not any(found[i] for i, x in truth_x.items() if x + 26 < 150)  # wholly in the zone
    assert all(found[i] for i, x in truth_x.items() if 180 < x < 280)  # wholly out of it
