"""The default method on synthetic scenes with exact truth (the issue's acceptance bar)."""

from __future__ import annotations

import statistics

import numpy as np
import pytest

from app.analysis.metrics import ObjectCounts, match_boxes
from app.sources.synthetic import MovingObject, Scene, standard_scenes
from app.vision.pipeline import Pipeline, PipelineConfig
from tests.conftest import lamplight, lit

SCENES = standard_scenes()
WITH_OBJECTS = [name for name, scene in SCENES.items() if scene.objects]
EMPTY = [name for name, scene in SCENES.items() if not scene.objects]
SETTLED_FRAMES = 6
"""Frames a track needs before its smoothed speed is judged."""
SPEED_TOLERANCE = {"dim": 0.10}
"""Median relative speed error allowed where not 0.05: eight grey levels from the ground,
the dim scene's blob edges jitter by a pixel against its 2 px a frame."""


def run_scene(scene: Scene, method: str = "adaptive") -> tuple[ObjectCounts, list[float], int]:
    pipeline = Pipeline(PipelineConfig(method=method), fps=scene.fps)
    counts = ObjectCounts()
    speed_errors: list[float] = []
    reported = 0
    age: dict[int, int] = {}
    for index in range(scene.frames):
        result = pipeline.process(scene.frame(index))
        truth = scene.truth(index)
        found = result.detections
        reported += len(found)
        counts.add([t.box for t in truth], [d.box for d in found])
        for d in found:
            age[d.track_id] = age.get(d.track_id, 0) + 1
        for t_index, d_index in match_boxes([t.box for t in truth], [d.box for d in found]):
            detection, true = found[d_index], truth[t_index]
            if age[detection.track_id] > SETTLED_FRAMES and true.speed_px_s > 0:
                speed_errors.append(abs(detection.speed_px_s - true.speed_px_s) / true.speed_px_s)
    return counts, speed_errors, reported


@pytest.mark.parametrize("name", WITH_OBJECTS)
def test_default_method_finds_objects_with_their_speed(name):
    counts, speed_errors, _ = run_scene(SCENES[name])
    assert counts.detection_rate >= 0.95, counts.as_dict()
    assert counts.false_alarm_rate <= 0.05, counts.as_dict()
    assert statistics.median(speed_errors) <= SPEED_TOLERANCE.get(name, 0.05)


@pytest.mark.parametrize("name", EMPTY)
def test_default_method_raises_no_alarm_on_empty_scenes(name):
    _, _, reported = run_scene(SCENES[name])
    assert reported == 0


def test_frame_difference_misses_the_slow_uniform_object_the_default_keeps():
    paper, _, _ = run_scene(SCENES["slow-uniform"], "frame-difference")
    ours, _, _ = run_scene(SCENES["slow-uniform"])
    assert paper.detection_rate < 0.5 < 0.95 <= ours.detection_rate


def test_a_dark_object_creeping_into_view_is_kept_whole_as_it_comes():
    # 30x70 at 8 px/s, a third of a pixel a frame at 640x480 and 25 fps: its inside
    # changes nowhere from one frame to the next, and the ghost step ate it from the rim
    # in where the rim matched the ground (found in 95% of frames, half the boxes round
    # only part of it).
    scene = Scene(
        name="creeping-in",
        size=(640, 480),
        fps=25.0,
        frames=362,
        objects=(MovingObject((-46, 300), (8.0, 0.0), (30, 70), 60),),
    )
    counts, _, _ = run_scene(scene)
    assert counts.detection_rate == 1.0, counts.as_dict()
    assert counts.false_alarm_rate <= 0.3, counts.as_dict()


def test_an_object_entering_the_view_has_its_own_speed_while_it_enters():
    # 60 px long at 20 px/s: three seconds with the frame's edge cutting it.
    scene = Scene(
        name="entering",
        frames=80,
        objects=(MovingObject((-100, 100), (20.0, 0.0), (60, 40), 200, first_frame=20),),
    )
    pipeline = Pipeline(PipelineConfig(), fps=scene.fps)
    entering: list[float] = []
    for index in range(scene.frames):
        result = pipeline.process(scene.frame(index))
        (truth,) = scene.truth(index) or (None,)
        if truth is None or truth.box.x > 0 or index < 40:  # all in, or not yet settled
            continue
        for detection in result.detections:
            assert detection.box.x == 0  # the only object, cut by the edge
            entering.append(detection.speed_px_s)
    assert len(entering) >= 20
    # The centroid of what shows moves at 10 px/s.
    assert statistics.median(entering) == pytest.approx(20.0, rel=0.05)


def test_an_object_in_view_when_the_light_switches_keeps_its_track():
    scene = SCENES["light-switch-crossing"]
    assert scene.light_switch_frame is not None
    pipeline = Pipeline(PipelineConfig(), fps=scene.fps)
    ids_around_the_switch: set[int] = set()
    for index in range(scene.frames):
        result = pipeline.process(scene.frame(index))
        if abs(index - scene.light_switch_frame) <= 15:
            ids_around_the_switch |= {d.track_id for d in result.detections}
    assert len(ids_around_the_switch) == 1


@pytest.mark.parametrize(
    ("grey", "seed"), [(40, 7), (45, 7), (55, 3), (55, 7), (70, 4), (150, 3), (150, 4)]
)
def test_a_dark_person_who_waits_stays_whole_and_leaves_no_ghost(grey, seed):
    # Dark clothes match the darker parts of the ground at the rim: the ghost step
    # once ate a person who stood still from there, ring by ring, and a person who
    # stopped was background after 30 frames; when they walked on, a ghost stayed.
    # Then one kept whole at a check could still be eaten: what the ghost step had
    # taken of the rim before it made the next check see a ghost's border. And one
    # whose clothes are nearer the ground's grey (70 and 150 on 110) was eaten from
    # the rim in the frames between their last step and the first check, which then
    # found too faint an outline to keep them.
    scene = Scene(
        name="waiting-dark",
        fps=25.0,
        frames=250,
        seed=seed,
        objects=(
            MovingObject((-20, 100), (50.0, 0.0), (28, 44), grey, first_frame=5, stop=(2.0, 6.0)),
        ),
    )
    counts, _, _ = run_scene(scene)
    assert counts.detection_rate >= 0.95, counts.as_dict()
    assert counts.false_alarm_rate <= 0.05, counts.as_dict()


@pytest.mark.parametrize(("seed", "brightness", "spread"), [(1, 60, 8), (2, 80, 10), (5, 60, 8)])
def test_a_soft_spot_of_lamplight_is_taken_in_and_not_kept_as_an_object(seed, brightness, spread):
    # A lamp comes on over a patch of textured ground: a soft, unsaturated bump of
    # light, taken in within a second or two. The last case was kept for 5 s, as a
    # stopped object, when the test of an object's outline was looser (CLEAR_EDGE
    # 1.5). Some spots still are (2 of 72 such spots: README, what it does not do).
    scene = Scene(name="lamp-spot", fps=25.0, frames=220, seed=seed)
    light = lamplight(scene.size, brightness, spread, (0.5, 0.5))
    pipeline = Pipeline(PipelineConfig(), fps=scene.fps)
    reported = []
    for index in range(scene.frames):
        frame = scene.frame(index)
        result = pipeline.process(lit(frame, light) if index >= 60 else frame)
        if index >= 60 and result.detections:
            reported.append(index - 60)
    assert not reported or reported[-1] <= 60, reported


@pytest.mark.parametrize("knock", [(4.0, 0.0), (0.0, 3.0), (3.0, 1.0)])
def test_a_small_knock_that_changes_only_the_edges_raises_nothing(knock):
    # At 640x480 a knock of a few pixels is one or two at detection size: the scene's
    # edges change, a tenth of the view, and the walker must stay the only object.
    scene = Scene(
        name="small-knock",
        size=(640, 480),
        fps=25.0,
        frames=120,
        camera_move_frame=60,
        camera_move=knock,
        objects=(MovingObject((-60, 200), (90.0, 0.0), (50, 80), 200, first_frame=20),),
    )
    pipeline = Pipeline(PipelineConfig(), fps=scene.fps)
    after = ObjectCounts()
    for index in range(scene.frames):
        result = pipeline.process(scene.frame(index))
        if index >= scene.camera_move_frame:
            after.add([t.box for t in scene.truth(index)], [d.box for d in result.detections])
    assert after.fp == 0, after.as_dict()
    assert after.detection_rate >= 0.95, after.as_dict()


def test_a_lane_that_look_alike_objects_cross_every_second_stays_seen():
    # Dark, alike things (a queue of the same cars, boxes on a belt) cross the same
    # lane every second, in view half the time. The model's second mode is for what
    # recurs at a pixel (leaves against sky); an object's inside, which replaced it
    # frame after frame, once kept it fresh until the lane's own objects were
    # background: the 16th crossing was 14% seen where the first was 97%.
    fps, crossings = 25.0, 16
    scene = Scene(
        name="busy-lane",
        fps=fps,
        frames=int((1 + crossings) * fps),
        objects=tuple(
            MovingObject(
                (-60 - 120.0 * (1 + i), 100),
                (120.0, 0.0),
                (60, 36),
                60,
                first_frame=int((1 + i) * fps),
                last_frame=int((1 + i) * fps + 4 * fps),
            )
            for i in range(crossings)
        ),
    )
    pipeline = Pipeline(PipelineConfig(), fps=fps)
    seen = [0] * crossings
    shown = [0] * crossings
    for index in range(scene.frames):
        mask = pipeline.process(scene.frame(index)).mask
        for truth in scene.truth(index):
            box = truth.box
            seen[truth.object_index] += int(
                (mask[box.y : box.y + box.h, box.x : box.x + box.w] > 0).sum()
            )
            shown[truth.object_index] += box.w * box.h
    coverage = [s / n for s, n in zip(seen, shown, strict=True)]
    assert coverage[0] > 0.9, coverage
    assert min(coverage[-4:]) > 0.5, coverage


@pytest.mark.parametrize(
    ("fps", "measured_later"), [(10.0, False), (25.0, False), (60.0, False), (60.0, True)]
)
def test_a_person_who_waits_is_kept_about_five_seconds_whatever_the_frame_rate(fps, measured_later):
    # The model's counts of frames stand for times, given at 25 fps: at 60 fps a
    # waiting person was taken into the background after 2.1 s, at 10 fps after 12.5.
    # A live camera's rate may be measured only after detection began (set_fps).
    walker = MovingObject((-40, 90), (100.0, 0.0), (30, 60), 60, stop=(2.0, 11.0))
    scene = Scene("wait", fps=fps, frames=int(11 * fps), objects=(walker,))
    pipeline = Pipeline(PipelineConfig(), fps=25.0 if measured_later else fps)
    if measured_later:
        for index in range(10):
            pipeline.process(scene.frame(index))
        pipeline.set_fps(fps)
    seen_after = []  # Seconds into the wait of each frame the person is seen in.
    for index in range(10 if measured_later else 0, scene.frames):
        result = pipeline.process(scene.frame(index))
        waited = index / fps - 2.0
        if waited >= 0 and result.detections:
            seen_after.append(waited)
    assert min(seen_after) < 0.1 and 4.5 <= max(seen_after) <= 6.0, (
        min(seen_after),
        max(seen_after),
    )


def test_a_walker_under_a_light_that_flickers_in_rolling_bands_is_seen_whole():
    # Mains light read by a rolling shutter: bands of rows 25% brighter or darker that
    # drift from frame to frame, and the whole view 10% with them. One gain for the
    # frame left the bands as motion: the threshold rose to 60, and the walker was
    # found in 70% of the frames, often as a strip (outside audit).
    walker = MovingObject((-30, 80), (60.0, 0.0), (24, 56), 60, first_frame=15)
    scene = Scene("bands", fps=30.0, frames=150, objects=(walker,))
    rows = np.arange(scene.size[1])[:, None, None]
    pipeline = Pipeline(PipelineConfig(), fps=scene.fps)
    counts = ObjectCounts()
    for index in range(scene.frames):
        phase = 2 * np.pi * 100.0 * index / scene.fps
        bands = 1 + 0.25 * np.sin(2 * np.pi * rows / (scene.size[1] / 3) + phase)
        light = bands * (1 + 0.1 * np.sin(phase + 0.3))
        frame = np.clip(scene.frame(index) * light, 0, 255).astype(np.uint8)
        result = pipeline.process(frame)
        if index >= 15:
            counts.add([t.box for t in scene.truth(index)], [d.box for d in result.detections])
    assert counts.detection_rate >= 0.95 and counts.false_alarm_rate <= 0.05, counts.as_dict()
