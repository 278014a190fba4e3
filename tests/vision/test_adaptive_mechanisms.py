"""Each mechanism of the adaptive method alone: a small synthetic case of what it is for,
which it handles with every mechanism on, and which goes wrong with it switched off
(``AdaptiveConfig``; the README's detection notes say what each is for)."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import replace

import cv2
import numpy as np
import pytest

from app.sources.synthetic import MovingObject, Scene
from app.vision.motion.adaptive import MECHANISMS, AdaptiveBackground, AdaptiveConfig
from app.vision.motion.base import MotionResult
from app.vision.pipeline import Pipeline
from app.vision.scene_background import SceneBackground
from app.vision.types import Mask

SIZE = (120, 160)
AREA = SIZE[0] * SIZE[1]


def ground(seed: int, contrast: float = 40.0, size: tuple[int, int] = SIZE) -> np.ndarray:
    """A smooth textured ground, grey 110 on average (float), ``size`` (rows, columns)."""
    rng = np.random.default_rng(seed)
    texture = cv2.GaussianBlur(rng.normal(0.0, 1.0, size), (0, 0), 2.0)
    return 110 + contrast * texture / texture.std()


def camera(picture: np.ndarray, rng: np.random.Generator, noise: float = 1.5) -> np.ndarray:
    """What a camera gives of ``picture``: with noise, 8-bit."""
    return np.clip(picture + rng.normal(0.0, noise, picture.shape), 0, 255).astype(np.uint8)


def run(
    config: AdaptiveConfig, frames: Iterable[np.ndarray], fps: float = 25.0
) -> list[MotionResult]:
    method = AdaptiveBackground(fps=fps, config=config)
    return [method.apply(frame) for frame in frames]


def masks_of(config: AdaptiveConfig, scene: Scene) -> list[Mask]:
    """Each frame's mask of a synthetic scene, its frames given grey to the method."""
    frames = (cv2.cvtColor(scene.frame(index), cv2.COLOR_BGR2GRAY) for index in range(scene.frames))
    return [result.mask for result in run(config, frames, scene.fps)]


def coverage(
    scene: Scene, masks: list[Mask], frames: range, inset: int, scale: int = 1
) -> list[float]:
    """Per frame of ``frames`` and object in view: the share of its box, less ``inset``
    pixels each side, that is moving (in masks ``scale`` times smaller than the scene)."""
    found = []
    for index in frames:
        for truth in scene.truth(index):
            box = truth.box
            top, bottom = box.y // scale + inset, (box.y + box.h) // scale - inset
            left, right = box.x // scale + inset, (box.x + box.w) // scale - inset
            found.append(share(masks[index], slice(top, bottom), slice(left, right)))
    return found


def share(mask: np.ndarray, rows: slice, cols: slice) -> float:
    """The share of a box of ``mask`` that is moving."""
    part = mask[rows, cols]
    return np.count_nonzero(part) / part.size


# --- the cases: each returns whether the method did what the mechanism is for ---------


def parked_object_stays_an_object(config: AdaptiveConfig) -> bool:
    """Something that drives in and parks is an object for seconds, not learned away
    while it stands (selective update: moving pixels do not teach the background)."""
    rng = np.random.default_rng(1)
    scene = ground(1)
    parked = scene.copy()
    parked[40:70, 60:100] = 220
    frames = [camera(scene, rng) for _ in range(25)] + [camera(parked, rng) for _ in range(90)]
    last = run(config, frames)[-1].mask
    return share(last, slice(40, 70), slice(60, 100)) > 0.9


def a_recurring_second_look_is_background(config: AdaptiveConfig) -> bool:
    """A patch that shows another face now and then (leaf against sky) is background once
    that face recurs (the second mode)."""
    rng = np.random.default_rng(2)
    scene = ground(2)
    other = scene.copy()
    other[30:70, 30:80] = 200
    frames = [camera(other if index % 4 == 3 else scene, rng) for index in range(120)]
    results = run(config, frames)
    late = [share(r.mask, slice(30, 70), slice(30, 80)) for r in results[80:]]
    return max(late) < 0.05


def swaying_leaves_go_quiet(config: AdaptiveConfig) -> bool:
    """A patch whose grey levels stir all the time (leaves, water) gets deaf: its pixels'
    own thresholds rise with their variability."""
    rng = np.random.default_rng(3)
    scene = ground(3)
    frames = []
    for _ in range(100):
        frame = scene.copy()
        frame[20:80, 90:150] += rng.normal(0.0, 14.0, (60, 60))
        frames.append(camera(frame, rng))
    results = run(config, frames)
    return np.mean([share(r.mask, slice(20, 80), slice(90, 150)) for r in results[60:]]) < 0.03


def low_contrast_object_comes_out_whole(config: AdaptiveConfig) -> bool:
    """An object only a little above the threshold but for a few strong spots is found
    whole as it steps in (hysteresis: weak pixels next to strong ones count)."""
    rng = np.random.default_rng(4)
    scene = ground(4, contrast=20.0)
    threshold = 10.0  # What the method measures on this camera (asserted below).
    stepped_in = scene.copy()
    stepped_in[40:70, 40:80] += 0.75 * threshold + 2  # Weak: above half the threshold.
    stepped_in[40:70:4, 40:80:4] += 3 * threshold  # Strong spots, 4 px apart.
    frames = [camera(scene, rng) for _ in range(30)] + [camera(stepped_in, rng, noise=0.5)]
    results = run(config, frames)
    assert results[-1].threshold == threshold
    return share(results[-1].mask, slice(41, 69), slice(41, 79)) > 0.8


def exposure_drift_is_not_motion(config: AdaptiveConfig) -> bool:
    """A camera's exposure that creeps up, a little each frame, moves nothing (the
    background is lit by the frame's gain)."""
    rng = np.random.default_rng(5)
    scene = ground(5)
    frames = [camera(scene * (1 + 0.012 * max(0, index - 20)), rng) for index in range(60)]
    results = run(config, frames)
    return all(np.count_nonzero(r.mask) < 0.01 * AREA and not r.global_change for r in results)


def a_light_switch_is_relearned(config: AdaptiveConfig) -> bool:
    """A lamp switched on over the whole view is learned at once, not reported."""
    rng = np.random.default_rng(7)
    scene = ground(7)
    lamp = np.linspace(1.2, 2.0, SIZE[1])[None, :]
    frames = [camera(scene, rng) for _ in range(25)] + [camera(scene * lamp, rng) for _ in range(5)]
    results = run(config, frames)
    return all(np.count_nonzero(r.mask) < 0.01 * AREA for r in results[25:])


def an_object_in_view_at_a_light_switch_stays_seen(config: AdaptiveConfig) -> bool:
    """Someone walking when the light switches is still seen where they walk (the old
    background under them, relit), not learned into the new one."""
    rng = np.random.default_rng(8)
    scene = ground(8)
    lamp = np.linspace(1.3, 1.7, SIZE[1])[None, :]
    frames = []
    for index in range(40):
        frame = scene.copy()
        x = 20 + index
        frame[40:80, x : x + 24] = 230
        frames.append(camera(frame * lamp if index >= 30 else frame, rng))
    results = run(config, frames)
    seen = [share(results[i].mask, slice(42, 78), slice(22 + i, 42 + i)) for i in range(31, 34)]
    return results[30].global_change and min(seen) > 0.5


def a_knocked_camera_is_followed(config: AdaptiveConfig) -> bool:
    """A camera knocked a few pixels sees the scene move; the model moves with it, and
    only what moves in the scene is motion."""
    rng = np.random.default_rng(9)
    scene = ground(9)
    knocked = cv2.warpAffine(
        scene, np.float64([[1, 0, -5], [0, 1, -3]]), SIZE[::-1], borderMode=cv2.BORDER_REFLECT
    )
    frames = [camera(scene, rng) for _ in range(30)] + [camera(knocked, rng) for _ in range(5)]
    results = run(config, frames)
    return all(np.count_nonzero(r.mask) < 0.02 * AREA for r in results[30:])


def the_ghost_of_what_left_is_eaten(config: AdaptiveConfig) -> bool:
    """Something in the first frame that drives off leaves no ghost where it stood."""
    rng = np.random.default_rng(10)
    scene = ground(10)
    frames = []
    for index in range(40):
        frame = scene.copy()
        x = 20 + 4 * max(0, index - 5)
        if x < SIZE[1]:
            frame[40:70, x : x + 30] = 220
        frames.append(camera(frame, rng))
    results = run(config, frames)
    return share(results[-1].mask, slice(40, 70), slice(20, 50)) < 0.05


def a_walker_under_rolling_bands_is_seen(config: AdaptiveConfig) -> bool:
    """Bands of mains light that drift each frame (a rolling shutter, 320x240) do not
    hide someone walking under them: each row is lit by its own gain."""
    rng = np.random.default_rng(6)
    scene = ground(6, size=(240, 320))
    rows = np.arange(240)[:, None]
    frames, lefts = [], []
    for index in range(110):
        phase = 2 * np.pi * 100.0 * index / 30.0
        bands = 1 + 0.25 * np.sin(2 * np.pi * rows / 80 + phase)
        frame = scene.copy()
        left = 4 * (index - 30)
        frame[80:136, max(left, 0) : max(left + 24, 0)] = 60
        frames.append(camera(frame * bands * (1 + 0.1 * np.sin(phase + 0.3)), rng))
        lefts.append(left)
    results = run(config, frames, fps=30.0)
    seen = [
        share(result.mask, slice(82, 134), slice(left + 2, left + 22))
        for result, left in zip(results, lefts, strict=True)
        if 0 <= left < 290
    ]
    return float(np.median(seen)) > 0.7


def a_stopped_object_is_taken_in_after_a_while(config: AdaptiveConfig) -> bool:
    """Something that parks is background after ``absorb_after`` frames (still regions:
    what stays "moving" without a change is absorbed)."""
    config = replace(config, absorb_after=15)
    rng = np.random.default_rng(11)
    scene = ground(11)
    frames = [camera(scene, rng) for _ in range(25)]
    for x in range(20, 50, 3):  # It drives in, then parks.
        frame = scene.copy()
        frame[50:70, x : x + 20] = 230
        frames.append(camera(frame, rng))
    frames += [frames[-1]] * 50
    return not run(config, frames)[-1].mask.any()


def a_dark_person_who_waits_stays_whole(config: AdaptiveConfig) -> bool:
    """Someone in dark clothes who stops for four seconds on textured ground stays one
    whole object (kept whole, out of the ghost step's reach), and leaves no ghost."""
    walker = MovingObject((-20, 100), (50.0, 0.0), (28, 44), 55, first_frame=5, stop=(2.0, 6.0))
    scene = Scene("waiting-dark", fps=25.0, frames=170, objects=(walker,))
    return min(coverage(scene, masks_of(config, scene), range(60, 150), inset=2)) > 0.8


def a_camouflaged_object_is_not_eaten_from_its_rim(config: AdaptiveConfig) -> bool:
    """An object whose grey the textured ground matches here and there crosses whole:
    near what stirs, the ghost step takes only settled neighbours, so a point of its rim
    that matches the ground does not pass the match on through its unchanging inside."""
    crossing = MovingObject((-70, 90), (30.0, 0.0), (60, 30), 150, first_frame=20)
    scene = Scene("camouflaged", fps=25.0, frames=150, objects=(crossing,))
    found = coverage(scene, masks_of(config, scene), range(60, scene.frames), inset=2)
    return float(np.median(found)) > 0.8


def a_dark_object_creeping_in_stays_whole(config: AdaptiveConfig) -> bool:
    """Something dark creeping into view a third of a pixel a frame (640x480 at 25 fps,
    detected at 320x240), its inside unchanged from frame to frame, is kept whole as it
    comes: the ghost step would eat it from the rim in, where the rim matches the
    ground."""
    creeper = MovingObject((-46, 300), (8.0, 0.0), (30, 70), 60)
    scene = Scene("creeping-in", size=(640, 480), fps=25.0, frames=362, objects=(creeper,))
    pipeline = Pipeline(fps=scene.fps)
    pipeline.method = AdaptiveBackground(fps=scene.fps, config=config)
    masks = [pipeline.process(scene.frame(index)).mask for index in range(scene.frames)]
    found = coverage(scene, masks, range(scene.frames), inset=1, scale=2)
    return float(np.percentile(found, 10)) > 0.6


def an_object_in_view_from_the_start_leaves_no_ghost(config: AdaptiveConfig) -> bool:
    """Started from the scene estimated ahead (``seed``), an object in view at the first
    frame that drives off is seen from there, and leaves no ghost behind."""
    rng = np.random.default_rng(12)
    scene = ground(12)
    frames = []
    for index in range(12):
        frame = scene.copy()
        x = 30 + 4 * index
        frame[40:70, x : x + 30] = 220
        frames.append(camera(frame, rng))
    method = AdaptiveBackground(config=config)
    method.seed(SceneBackground(scene.astype(np.float32), np.zeros(SIZE, np.float32), False))
    results = [method.apply(frame) for frame in frames]
    ghost = [share(r.mask, slice(40, 70), slice(30, 42)) for r in results[4:]]
    return max(ghost) < 0.05


def a_slow_object_does_not_teach_its_own_pixels_deaf(config: AdaptiveConfig) -> bool:
    """Something dark creeping a sixth of a pixel a frame stays seen: the parts of it
    that match the ground look still, and next to motion they teach their variability
    slowly, or they would grow deaf to the object, then lose it piece by piece."""
    creeper = MovingObject((-23, 150), (4.0, 0.0), (15, 35), 60)
    scene = Scene("creeping-small", fps=25.0, frames=362, objects=(creeper,))
    return min(coverage(scene, masks_of(config, scene), range(150, scene.frames), inset=1)) > 0.5


CASES: dict[str, Callable[[AdaptiveConfig], bool]] = {
    "selective_update": parked_object_stays_an_object,
    "second_mode": a_recurring_second_look_is_background,
    "variability": swaying_leaves_go_quiet,
    "near_motion_teaching": a_slow_object_does_not_teach_its_own_pixels_deaf,
    "learning_phase": the_ghost_of_what_left_is_eaten,
    "hysteresis": low_contrast_object_comes_out_whole,
    "frame_gain": exposure_drift_is_not_motion,
    "row_gains": a_walker_under_rolling_bands_is_seen,
    "light_switch": a_light_switch_is_relearned,
    "relight_objects": an_object_in_view_at_a_light_switch_stays_seen,
    "follow_view": a_knocked_camera_is_followed,
    "ghost_absorption": the_ghost_of_what_left_is_eaten,
    "stirring_guard": a_camouflaged_object_is_not_eaten_from_its_rim,
    "still_regions": a_stopped_object_is_taken_in_after_a_while,
    "keep_stopped": a_dark_person_who_waits_stays_whole,
    "keep_plain_movers": a_dark_object_creeping_in_stays_whole,
    "start_from_scene": an_object_in_view_from_the_start_leaves_no_ghost,
}


def test_every_mechanism_has_a_case():
    assert list(CASES) == list(MECHANISMS)


@pytest.mark.parametrize("mechanism", MECHANISMS)
def test_each_mechanism_handles_its_case_and_is_missed_when_off(mechanism):
    case = CASES[mechanism]
    assert case(AdaptiveConfig()), f"{case.__name__} fails with every mechanism on"
    off = AdaptiveConfig(**{mechanism: False})
    assert not case(off), f"{case.__name__} passes with {mechanism} off: it shows nothing of it"
