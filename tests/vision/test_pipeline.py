import cv2
import numpy as np
import pytest

from app.analysis.metrics import ObjectCounts
from app.sources.synthetic import MovingObject, Scene
from app.vision.pipeline import Pipeline, PipelineConfig

SCENE = Scene(
    name="vga",
    size=(640, 480),
    fps=25.0,
    frames=40,
    objects=(MovingObject((50, 200), (100.0, 0.0), (60, 90), 220, first_frame=5),),
)


def test_every_stage_is_timed_and_boxes_come_back_in_input_pixels():
    pipeline = Pipeline(PipelineConfig(), fps=SCENE.fps)
    results = [pipeline.process(SCENE.frame(i)) for i in range(SCENE.frames)]
    stages = {
        "grayscale",
        "histogram",
        "downscale",
        "denoise",
        "enhance",
        "segment",
        "morphology",
        "blobs",
        "track",
    }
    assert stages <= set(pipeline.timings)
    assert all(len(pipeline.timings[s]) == SCENE.frames for s in stages)
    # Cleaning and measuring run only on frames where something moved: not on the
    # first, which the model learns from (it costs that frame nothing).
    assert all(
        pipeline.timings[s][0] == 0.0 < max(pipeline.timings[s]) for s in ("morphology", "blobs")
    )
    last = results[-1]
    assert last.scale == 2.0 and last.mask.shape == (240, 320)
    (truth,) = SCENE.truth(SCENE.frames - 1)
    (found,) = last.detections
    assert found.box.iou(truth.box) > 0.8
    assert last.time_s == (SCENE.frames - 1) / SCENE.fps


def test_a_reduced_copy_gives_boxes_speeds_and_areas_of_the_original():
    """What a camera does with a JPEG decoded at half scale: same objects, same units."""
    full = Pipeline(PipelineConfig(), fps=SCENE.fps)
    reduced = Pipeline(PipelineConfig(), fps=SCENE.fps)
    for i in range(SCENE.frames):
        frame = SCENE.frame(i)
        half = cv2.resize(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), (320, 240), cv2.INTER_AREA)
        expected = full.process(frame)
        got = reduced.process(half, frame_size=(640, 480))
    assert got.scale == expected.scale == 2.0
    (a,) = expected.detections
    (b,) = got.detections
    assert b.box.iou(a.box) > 0.9
    assert b.area == pytest.approx(a.area, rel=0.1)
    assert b.speed_px_s == pytest.approx(a.speed_px_s, rel=0.05)
    assert b.speed_px_s == pytest.approx(100.0, rel=0.1)


def test_full_resolution_detection_when_asked():
    pipeline = Pipeline(PipelineConfig(detect_width=0), fps=SCENE.fps)
    result = pipeline.process(SCENE.frame(0))
    assert result.scale == 1.0 and result.mask.shape == (480, 640)


def test_sensitivity_and_min_area_changes_act_on_the_next_frame():
    pipeline = Pipeline(PipelineConfig(), fps=SCENE.fps)
    for i in range(20):
        found = pipeline.process(SCENE.frame(i)).detections
    assert found
    pipeline.set_min_area(60 * 90 * 2)
    assert not pipeline.process(SCENE.frame(20)).detections
    pipeline.set_min_area(100)
    pipeline.set_sensitivity(255)
    assert not pipeline.process(SCENE.frame(21)).detections
    pipeline.set_sensitivity(None)
    assert pipeline.process(SCENE.frame(22)).detections


def test_grey_statistics_are_of_the_input_frame():
    frame = np.zeros((100, 100, 3), np.uint8)
    frame[:50] = 200
    result = Pipeline().process(frame)
    assert result.stats.mean == 100.0
    assert result.stats.std == 100.0
    assert result.gray.shape == (100, 100)
    assert cv2.countNonZero(result.mask) == 0
    # A live camera does without them (its histogram viewers measure what they draw).
    assert Pipeline(PipelineConfig(grey_stats=False)).process(frame).stats is None


def test_method_swap_keeps_tracks_and_sensitivity():
    pipeline = Pipeline(PipelineConfig(sensitivity=20), fps=SCENE.fps)
    for i in range(15):
        pipeline.process(SCENE.frame(i))
    pipeline.set_method("knn")
    assert pipeline.method.name == "knn" and pipeline.method.sensitivity == 20
    assert pipeline.process(SCENE.frame(15)).index == 15


@pytest.mark.parametrize("method", ["knn", "mog2"])
def test_objects_apart_stay_apart_after_a_method_calls_a_whole_frame_motion(method):
    # OpenCV's KNN calls the whole of its first frames motion: a track took the frame's
    # size, and every object after it was joined into its one box (4 walkers in rows
    # as one 606x372 box at 3 px/s).
    walkers = tuple(
        MovingObject((-30 - 20 * row, 20 + 55 * row), (80.0, 0.0), (24, 40), 60 + 40 * row)
        for row in range(4)
    )
    scene = Scene("rows", frames=100, objects=walkers)
    pipeline = Pipeline(PipelineConfig(method=method), fps=scene.fps)
    counts = ObjectCounts()
    for index in range(scene.frames):
        result = pipeline.process(scene.frame(index))
        if index >= 30:
            counts.add([t.box for t in scene.truth(index)], [d.box for d in result.detections])
    assert counts.detection_rate >= 0.8 and counts.false_alarm_rate <= 0.2, counts.as_dict()
