"""The demo camera's street scene: a place in colour, with exact truth the detector meets."""

from __future__ import annotations

import itertools
import statistics
from collections import Counter, defaultdict
from dataclasses import replace

import numpy as np
import pytest

from app.analysis.metrics import ObjectCounts, match_boxes
from app.core.config import Settings
from app.events.alarm import AlarmLogic
from app.sources.demo_scene import GAP_S, MIN_VISIBLE_FRACTION, StreetScene
from app.sources.demo_sprites import Person
from app.sources.live import DemoSource, demo_scene
from app.vision.detections import Box
from app.vision.pipeline import Pipeline, PipelineConfig

SCENE = demo_scene()


def groups(scene: StreetScene) -> list[tuple[int, int]]:
    """The runs of frames with something in view, (first, last), less than a second
    apart joined (a foot at the picture's edge as someone leaves it, say)."""
    runs: list[tuple[int, int]] = []
    for index in range(scene.frames):
        if scene.in_view(index):
            if runs and runs[-1][1] >= index - scene.fps:
                runs[-1] = (runs[-1][0], index)
            else:
                runs.append((index, index))
    return runs


def test_the_demo_is_a_street_in_colour_at_640x480_that_loops() -> None:
    source = DemoSource()
    assert source.paced and source.fps == 15.0 and source.scene is SCENE
    assert source.description == "demo scene 640x480"
    frames = [source.read().image() for _ in range(SCENE.frames + 1)]
    assert frames[0].shape == (480, 640, 3) and frames[0].dtype == np.uint8
    assert (frames[-1] == frames[0]).all(), "the loop starts again"
    blue, green, red = (frames[0][..., c].astype(int) for c in range(3))
    assert np.abs(red - blue).mean() > 15 and np.abs(green - blue).mean() > 10, "in colour"


def test_the_loop_begins_and_ends_empty_and_quiet_gaps_part_the_passings() -> None:
    runs = groups(SCENE)
    assert runs[0][0] > 0 and runs[-1][1] < SCENE.frames - 1
    assert len(runs) == 5  # A walker, a car, two people, one crossing the road, a car.
    gaps = [b[0] - a[1] - 1 for a, b in itertools.pairwise(runs)]
    gaps.append(SCENE.frames - 1 - runs[-1][1] + runs[0][0])  # Across the loop's seam.
    assert min(gaps) / SCENE.fps >= GAP_S - 0.2, gaps
    assert Settings().quiet_s < GAP_S - 0.2  # So each run is an event of its own.


@pytest.mark.parametrize("index", range(0, SCENE.frames, 23))
def test_truth_is_exactly_what_is_drawn(index: int) -> None:
    clean = replace(SCENE, noise_sigma=0.0)
    changed = (clean.frame(index) != SCENE.street).any(axis=2)
    in_view = clean.in_view(index)
    covered = np.zeros_like(changed)
    for _, box, _ in in_view:
        covered[box.y : box.y + box.h, box.x : box.x + box.w] = True
    assert not (changed & ~covered).any(), "drawn outside every box"
    truth = clean.truth(index)
    assert {t.object_index for t in truth} == {
        i for i, _, share in in_view if share >= MIN_VISIBLE_FRACTION
    }
    for true in truth:
        box = true.box
        ys, xs = np.nonzero(changed[box.y : box.y + box.h, box.x : box.x + box.w])
        drawn = Box(box.x + xs.min(), box.y + ys.min(), np.ptp(xs) + 1, np.ptp(ys) + 1)
        assert drawn.iou(box) >= 0.95, (drawn, box)
        assert true.speed_px_s > 0


def test_walkers_swing_their_legs_as_they_go() -> None:
    for k, passing in enumerate(SCENE.passings):
        if not isinstance(passing.look, Person):
            continue
        steps = [t for i in range(SCENE.frames) for t in SCENE.truth(i) if t.object_index == k]
        widths = [t.box.w for t in steps if t.box.x > 0 and t.box.x + t.box.w < 640]
        assert max(widths) > 1.25 * min(widths), (k, min(widths), max(widths))
        heights = [t.box.h for t in steps]
        if passing.start[1] == passing.end[1]:  # Along the street: its size stays.
            assert max(heights) - min(heights) <= 0.1 * max(heights)
        else:  # Crossing it, away from the camera: it gets smaller.
            assert heights[-1] < 0.7 * heights[0]


def test_the_default_method_finds_everyone_and_every_car_and_nothing_else() -> None:
    # A demo camera started at frame 0, watched over two loops: every passer-by found
    # with a box that matches, at its speed; nothing on an empty street; an alarm each
    # time someone comes by, under the server's own quiet and gap seconds.
    scene = SCENE
    pipeline = Pipeline(PipelineConfig(), fps=scene.fps)
    settings = Settings()
    alarms = AlarmLogic(settings.quiet_s, settings.alarm_gap_s)
    starts, empty_detections = [], 0
    counts = [ObjectCounts(), ObjectCounts()]
    found: Counter[int] = Counter()
    shown: Counter[int] = Counter()
    speed_errors: defaultdict[int, list[float]] = defaultdict(list)
    for n in range(2 * scene.frames):
        index = n % scene.frames
        result = pipeline.process(scene.frame(index))
        if alarms.update(n, n / scene.fps, result.detections).started:
            starts.append(index)
        if not scene.in_view(index):
            empty_detections += len(result.detections)
        seen = [d for d in result.detections if not scene.on_partly_visible(index, d.box)]
        truth = scene.truth(index)
        counts[n // scene.frames].add([t.box for t in truth], [d.box for d in seen])
        shown.update(t.object_index for t in truth)
        for t, d in match_boxes([t.box for t in truth], [d.box for d in seen]):
            found[truth[t].object_index] += 1
            error = abs(seen[d].speed_px_s - truth[t].speed_px_s) / truth[t].speed_px_s
            speed_errors[truth[t].object_index].append(error)
    for loop in counts:
        assert loop.detection_rate >= 0.9 and loop.false_alarm_rate <= 0.1, loop.as_dict()
    for k in shown:
        assert found[k] >= 0.8 * shown[k], (k, found[k], shown[k])
        assert statistics.median(speed_errors[k]) <= 0.1, k
    assert empty_detections == 0
    assert [first for first, _ in groups(scene)] * 2 == pytest.approx(starts, abs=8), starts


def test_the_street_is_painted_the_same_every_time() -> None:
    again = StreetScene(SCENE.passings, SCENE.frames)  # Painted afresh.
    assert again.street is not SCENE.street
    for index in (0, 200, 700):
        assert (again.frame(index) == SCENE.frame(index)).all()
