"""The empty scene of a clip, estimated from frames sampled ahead (offline mode)."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from app.sources.synthetic import MovingObject, Scene
from app.vision.pipeline import Pipeline
from app.vision.scene_background import (
    LEAST_SAMPLES,
    EvenSample,
    SceneBackground,
    estimate_recent_scene,
    estimate_scene_background,
)
from tests.conftest import lamplight, lit

CLOSE = 6.0
"""Grey levels: an estimate this near the empty scene is right (the camera noise is 2)."""


def samples_of(scene: Scene, size: int = 32) -> list[np.ndarray]:
    """The scene's frames as detection sees them, sampled as the background scan does."""
    pipeline = Pipeline(fps=scene.fps)
    sample: EvenSample[np.ndarray] = EvenSample(size)
    for frame in scene.frames_iter():
        sample.offer(lambda frame=frame: pipeline.prepare(frame))
    return sample.items


def empty_scene(scene: Scene, frame: int = 0) -> np.ndarray:
    """The scene without its objects or noise, as detection sees it."""
    picture = replace(scene, objects=(), noise_sigma=0.0).frame(frame)
    return Pipeline(fps=scene.fps).prepare(picture).astype(np.float32)


def share_right(estimate: SceneBackground, truth: np.ndarray) -> float:
    return float(np.mean(np.abs(estimate.background - truth) <= CLOSE))


def estimated(scene: Scene) -> SceneBackground:
    estimate = estimate_scene_background(samples_of(scene))
    assert estimate is not None
    return estimate


def test_even_sample_keeps_evenly_spaced_items_and_builds_few():
    built = []
    sample: EvenSample[int] = EvenSample(8)
    for number in range(1000):
        sample.offer(lambda number=number: built.append(number) or number)
    items = sample.items
    assert items[0] == 0
    assert 8 <= len(items) < 16
    assert set(np.diff(items)) == {sample.stride}
    assert items[-1] > 1000 - 2 * sample.stride  # It reaches the end of the stream.
    assert len(built) < 100  # Most items are never built.


def test_too_few_samples_give_no_estimate():
    frames = [np.full((24, 32), 100, np.uint8)] * (LEAST_SAMPLES - 1)
    assert estimate_scene_background(frames) is None


def test_a_slow_car_in_view_throughout_is_not_taken_for_the_scene():
    # In view from frame 0 to the last, it covers the middle of its path for more than
    # half the clip: a median over all samples takes the car for the scene there.
    scene = Scene(
        "slow-car",
        frames=120,
        objects=(MovingObject((40, 120), (15.0, 0.0), (70, 35), 30, textured=False),),
    )
    truth = empty_scene(scene)
    samples = samples_of(scene)
    plain_median = np.median(np.stack(samples), axis=0)
    assert np.count_nonzero(np.abs(plain_median - truth) > 20) > 500
    estimate = estimate_scene_background(samples)
    assert estimate is not None and not estimate.view_changed
    assert share_right(estimate, truth) >= 0.995


@pytest.mark.parametrize(
    "car",
    [
        # Parked at frame 0, drives off after 3 s: the scene there is the end's.
        MovingObject((100, 100), (40.0, 0.0), (60, 30), 60, textured=False, stop=(0.0, 3.0)),
        # Drives in and parks after 4 s: the scene there is the start's.
        MovingObject((-60, 100), (40.0, 0.0), (60, 30), 60, textured=False, stop=(4.0, 99.0)),
    ],
    ids=["leaves", "arrives"],
)
def test_a_car_at_one_end_only_is_left_out_by_its_outline(car):
    scene = Scene("parking", frames=135, objects=(car,))
    estimate = estimated(scene)
    assert share_right(estimate, empty_scene(scene)) >= 0.995


@pytest.mark.parametrize(
    "change",
    [{"light_switch_frame": 45}, {"camera_move_frame": 45, "camera_move": (5.5, 2.5)}],
    ids=["light-switch", "knocked-camera"],
)
def test_a_change_of_the_whole_view_leaves_the_scene_before_it(change):
    walker = MovingObject((-20, 100), (45.0, 0.0), (28, 44), 200, first_frame=5)
    scene = Scene("changed", frames=90, objects=(walker,), **change)
    estimate = estimated(scene)
    assert estimate.view_changed
    assert share_right(estimate, empty_scene(scene)) >= 0.99


def noisy(picture: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return np.clip(picture + rng.normal(0.0, 2.0, picture.shape), 0, 255).astype(np.uint8)


def test_a_cloud_s_shadow_that_moved_on_leaves_the_start_s_picture():
    # Plain ground with a soft shadow, which drifts away over the clip: neither end's
    # picture shows an outline where they disagree. The scene is what frame 0 shows;
    # the end's picture there would be motion in the first frames.
    rng = np.random.default_rng(1)
    rows, cols = np.mgrid[0:120, 0:160]

    def shadowed(x: float) -> np.ndarray:
        shade = np.exp(-((cols - x) ** 2 + (rows - 60.0) ** 2) / (2 * 22.0**2))
        return 120.0 * (1.0 - 0.45 * shade)

    samples = [noisy(shadowed(40.0 + 1.5 * i), rng) for i in range(32)]
    estimate = estimate_scene_background(samples)
    assert estimate is not None
    assert np.mean(np.abs(estimate.background - shadowed(40.0)) <= CLOSE) >= 0.99


def test_a_car_whose_rim_is_near_the_ground_s_grey_is_left_out_when_it_leaves():
    # A silver car with dark windows on tarmac, there at the start, gone by the end: its
    # rim steps little against the ground, its inside much; the rim is the outline.
    rng = np.random.default_rng(3)
    texture = cv2.GaussianBlur(rng.normal(0.0, 1.0, (120, 160)), (0, 0), 1.0)
    ground = 120.0 + 8.0 * texture / texture.std()
    car = ground.copy()
    car[30:90, 60:85] = 100.0
    car[34:86, 64:81] = 30.0
    samples = [noisy(car if i < 12 else ground, rng) for i in range(32)]
    estimate = estimate_scene_background(samples)
    assert estimate is not None
    inside = (slice(34, 86), slice(64, 81))  # Where the rim steps less, the ends agree.
    assert np.mean(np.abs(estimate.background[inside] - ground[inside]) <= CLOSE) >= 0.99


def test_a_camera_that_panned_leaves_the_scene_before_it():
    # A few signs on plain walls, the camera turned a fifth of the view half way: the
    # signs seen at the start are the scene, not objects that left.
    rng = np.random.default_rng(2)
    wall = np.full((120, 240), 110.0)
    for x, y in ((20, 15), (70, 40), (120, 80), (160, 20), (200, 95), (100, 100)):
        wall[y : y + 12, x : x + 10] = 200.0
    start, panned = wall[:, :160], wall[:, 32:192]
    samples = [noisy(start if i < 16 else panned, rng) for i in range(32)]
    estimate = estimate_scene_background(samples)
    assert estimate is not None and estimate.view_changed
    assert np.mean(np.abs(estimate.background - start) <= CLOSE) >= 0.99


def test_swaying_leaves_show_as_variability_where_they_are():
    x, y, w, h = region = (200, 20, 100, 120)
    scene = Scene("sway", frames=120, sway_region=region)
    variability = estimated(scene).variability
    inside = np.zeros(variability.shape, bool)
    inside[y : y + h, x : x + w] = True
    assert np.median(variability[inside]) > 3 * np.median(variability[~inside])
    assert np.median(variability[~inside]) < 2.0  # The camera noise alone, elsewhere.


def glances_of(scene: Scene, frames: range) -> list[np.ndarray]:
    pipeline = Pipeline(fps=scene.fps)
    return [pipeline.prepare(scene.frame(index)) for index in frames]


def test_a_live_camera_s_recent_scene_leaves_out_who_walked_through():
    walker = MovingObject((-20, 100), (60.0, 0.0), (40, 40), 200)
    standing = MovingObject((220, 40), (0.0, 0.0), (30, 50), 40)  # First: textures go by place.
    scene = Scene("yard", fps=25.0, frames=200, objects=(standing, walker))
    recent = estimate_recent_scene(glances_of(scene, range(0, 81, 10)))
    assert recent is not None
    # The walker is not in the scene; who stood still all along is (no motion, no alarm).
    stood = replace(scene, objects=(standing,), noise_sigma=0.0).frame(0)
    truth = Pipeline(fps=scene.fps).prepare(stood).astype(np.float32)
    assert share_right(recent, truth) >= 0.995


@pytest.mark.parametrize("noise", [2.0, 6.0])
def test_a_light_that_came_on_just_before_activate_is_scene(noise):
    # A lamp came on over part of the view two glances before Activate: the median of
    # the glances still shows it off, and the lit patch was motion for half a second.
    scene = Scene("lamp", frames=100, noise_sigma=noise)
    light = lamplight(scene.size, 50.0, 35.0, (0.3, 0.4))
    pipeline = Pipeline(fps=scene.fps)
    frames = [scene.frame(index) for index in range(0, 100, 10)]
    glances = [pipeline.prepare(f) for f in frames[:7]]
    glances += [pipeline.prepare(lit(f, light)) for f in frames[7:9]]
    recent = estimate_recent_scene(glances, pipeline.prepare(lit(frames[9], light)))
    assert recent is not None
    truth = pipeline.prepare(lit(replace(scene, noise_sigma=0.0).frame(0), light))
    assert share_right(recent, truth.astype(np.float32)) >= 0.99
    # The lit patch is as variable as the rest of the ground: its samples from before
    # the light came on count about the scene they show.
    under = light > 12
    unlit = estimate_recent_scene([pipeline.prepare(f) for f in frames[:9]])
    assert unlit is not None
    assert np.median(recent.variability[under]) <= np.median(unlit.variability[under]) + 0.1


@pytest.mark.parametrize(
    ("speed", "intensity", "textured", "last_glance"), [(30, 110, True, 12), (60, 140, False, 1)]
)
def test_someone_walking_at_activate_stays_out_of_the_scene(
    speed, intensity, textured, last_glance
):
    # The last glance may be a moment before Activate: the walker is in it and in the
    # frame at Activate, nearly where they are. That agreement is no scene.
    activate = 260
    walker = MovingObject(
        (150 - speed * activate / 25, 100), (float(speed), 0.0), (30, 60), intensity, textured
    )
    scene = Scene("walking", frames=300, objects=(walker,), background_contrast=100)
    glances = glances_of(scene, range(activate - last_glance - 200, activate - last_glance + 1, 25))
    now = glances_of(scene, range(activate, activate + 1))[0]
    recent = estimate_recent_scene(glances, now)
    assert recent is not None
    assert share_right(recent, empty_scene(scene)) >= 0.999


@pytest.mark.parametrize("intensity", [200, 60])
def test_someone_who_stopped_just_before_activate_is_not_scene(intensity):
    # In the newest three glances, still: the median of those shows them, but they are
    # an outline on the ground, not a change of the scene.
    stopped = MovingObject((140, 90), (0.0, 0.0), (24, 56), intensity, first_frame=70)
    scene = Scene("stopped", frames=100, objects=(stopped,))
    recent = estimate_recent_scene(glances_of(scene, range(0, 91, 10)))
    assert recent is not None
    assert share_right(recent, empty_scene(scene)) >= 0.995


def test_a_live_camera_s_recent_scene_needs_enough_glances_of_one_view():
    scene = Scene("lit", frames=100, light_switch_frame=40)
    assert estimate_recent_scene(glances_of(scene, range(0, 40, 10))) is None  # Four.
    assert estimate_recent_scene(glances_of(scene, range(0, 41, 5))) is None  # Lit at the end.
    assert estimate_recent_scene(glances_of(scene, range(0, 40, 5))) is not None


@pytest.mark.parametrize("shape", [(1, 1), (1, 40), (40, 1), (3, 50), (12, 12)])
def test_tiny_pictures_are_estimated_without_failing(shape):
    rng = np.random.default_rng(3)
    frames = [rng.integers(90, 110, shape, dtype=np.uint8) for _ in range(40)]
    for estimate in (estimate_scene_background(frames), estimate_recent_scene(frames[:9])):
        assert estimate is not None and estimate.background.shape == shape
        assert np.isfinite(estimate.background).all() and np.isfinite(estimate.variability).all()
        assert estimate.background.min() >= 85 and estimate.background.max() <= 115
