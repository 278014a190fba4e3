"""The scene sweep: every method on a broad set of synthetic scenes with exact truth,
compared with a checked-in baseline, so a change's effect on every scene is one command away.

    python bench/scenes.py [--method adaptive[,mog2,...]] [--scenes PATTERN[,PATTERN]]
                           [--jobs N] [--baseline FILE] [--write-baseline] [--check] [--list]

Prints per scene DR and FAR (per object per frame, as bench/accuracy.py scores them),
the confirmed tracks and the events, the figures pooled over every scene and per group,
then what changed against the baseline (bench/scenes_baseline.json), down to a digest
of every frame's motion mask and of every tracked row. See bench/README.md.
"""

from __future__ import annotations

import argparse
import fnmatch
import hashlib
import json
import multiprocessing
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import cv2
from _common import (
    REPO_ROOT,
    WITHOUT,
    Cell,
    fmt,
    method_label,
    parse_methods,
    print_environment,
    print_table,
    run_pipeline,
    without,
)
from scene_effects import (
    CloudShadow,
    EffectScene,
    Exposure,
    FlickerBands,
    InfraredSwitch,
    Lamp,
    Pan,
    Rain,
    Renderable,
    Shake,
    Snow,
    seen_through,
)

from app.analysis.metrics import DEFAULT_IOU, ObjectCounts
from app.events.alarm import AlarmLogic
from app.sources.synthetic import MovingObject, Scene, in_view_scenes, standard_scenes
from app.vision.motion import DEFAULT_METHOD
from app.vision.motion.adaptive import MECHANISMS
from app.vision.pipeline import FrameResult
from app.vision.types import Image

BASELINE = REPO_ROOT / "bench" / "scenes_baseline.json"
QUIET_S = 1.0
"""Seconds without a detection that end an event, as ``vigil analyze`` counts them."""

VGA = (640, 480)
OPENCV_SEED = 1
"""OpenCV's random generator is set to this before each method's run of a scene."""

# --- the scenes ---------------------------------------------------------------------------


@dataclass(frozen=True)
class SweepScene:
    scene: Renderable
    group: str
    scan: bool = True
    """Start from the empty scene the background scan finds, as ``vigil analyze`` does; False:
    learn the first frame, as a live camera does that was activated as it connected."""


def walker(
    x: float,
    y: float,
    vx: float,
    grey: int = 200,
    size: tuple[int, int] = (28, 44),
    vy: float = 0.0,
    stop: tuple[float, float] | None = None,
) -> MovingObject:
    """A textured object (a person at 320x240 by default) at (x, y) at time 0, moving
    ``vx``, ``vy`` pixels a second. It is there from the first frame: one that comes in
    starts out of view (``first_frame`` would make it pop up where it is by then)."""
    return MovingObject((x, y), (vx, vy), size, grey, stop=stop)


def person(x: float, y: float, vx: float, grey: int = 200, vy: float = 0.0) -> MovingObject:
    """A person at 640x480: 40x90 pixels."""
    return walker(x, y, vx, grey, (40, 90), vy)


def camera_scenes() -> list[Scene | EffectScene]:
    pan_view = Scene("pan_walker", size=VGA, fps=25.0, frames=150, objects=(person(-50, 250, 70),))
    # 2.4 px a frame for 2 s: from the start, or once the scene is long known.
    pan, late_pan = Pan(start=2, frames=50, step=(2.4, 0.0)), Pan(40, 50, (2.4, 0.0))
    walker_320 = (walker(-30, 100, 45),)
    return [
        seen_through(pan_view, pan),
        seen_through(replace(pan_view, name="pan_empty", objects=()), pan),
        seen_through(replace(pan_view, name="pan_late_walker"), late_pan),
        # A quarter of a pixel a frame at detection size: too slow to be followed.
        seen_through(
            replace(pan_view, name="pan_slow_walker", frames=200),
            Pan(start=40, frames=150, step=(0.5, 0.0)),
        ),
        seen_through(
            Scene("pan_diagonal_walker", frames=90, objects=walker_320),
            Pan(start=30, frames=30, step=(1.5, -1.0)),
        ),
        # Two pixels at detection size: only the scene's edges change.
        Scene(
            "knock_small_640",
            size=VGA,
            fps=25.0,
            frames=120,
            camera_move_frame=60,
            camera_move=(4.0, 0.0),
            objects=(walker(-110, 200, 90, size=(50, 80)),),
        ),
        Scene(
            "knock_big_walker",
            frames=90,
            camera_move_frame=45,
            camera_move=(-14.0, 7.0),
            objects=walker_320,
        ),
        # A knock that changes the exposure too: taken for a light switch.
        EffectScene(
            Scene(
                "knock_exposure_walker",
                frames=90,
                camera_move_frame=45,
                camera_move=(6.0, 3.0),
                objects=walker_320,
            ),
            (Exposure(start=45, end=45, gain=1.3),),
        ),
        seen_through(Scene("shake_walker", frames=120, objects=walker_320), Shake(2.5)),
        seen_through(Scene("shake_empty", frames=90), Shake(2.5)),
    ]


def light_scenes() -> list[Scene | EffectScene]:
    crossing = (walker(-30, 100, 40),)
    waits = (walker(-30, 100, 40, stop=(2.5, 6.0)),)
    bands_walker = (walker(-60, 80, 60, grey=60, size=(24, 56)),)
    lamp = Scene("lamp_spot_empty", fps=25.0, frames=180, seed=5)
    return [
        # Lights out over a lamp's uneven light: darker everywhere, by 40 to 60%.
        Scene(
            "light_off_walker", frames=90, light_switch_frame=40, light_gain=0.55, objects=crossing
        ),
        Scene("light_off_empty", frames=60, light_switch_frame=30, light_gain=0.5),
        Scene(
            "light_on_640_walker",
            size=VGA,
            fps=25.0,
            frames=150,
            light_switch_frame=75,
            objects=(person(-80, 200, 80),),
        ),
        EffectScene(
            Scene("flicker_walker", fps=30.0, frames=150, objects=bands_walker), (FlickerBands(),)
        ),
        EffectScene(Scene("flicker_empty", fps=30.0, frames=90), (FlickerBands(),)),
        # The switch to infrared while someone walks through the view, and stands in it.
        EffectScene(Scene("ir_switch_walker", frames=120, objects=crossing), (InfraredSwitch(60),)),
        EffectScene(Scene("ir_switch_waiting", frames=150, objects=waits), (InfraredSwitch(60),)),
        EffectScene(Scene("ir_switch_empty", frames=90), (InfraredSwitch(45),)),
        EffectScene(
            Scene("exposure_ramp_walker", frames=120, objects=crossing),
            (Exposure(start=20, end=80, gain=1.4),),
        ),
        EffectScene(
            Scene("exposure_fall_empty", frames=120), (Exposure(start=15, end=60, gain=0.6),)
        ),
        EffectScene(Scene("exposure_hunt_empty", frames=150), (Exposure(hunt=0.25, period_s=2.0),)),
        # A lamp comes on: a small soft spot (this one is kept as a stopped object, 5 s), a
        # wide pool of light, and a spot beside someone walking.
        EffectScene(lamp, (Lamp(40, 60.0, 8.0),)),
        EffectScene(
            replace(lamp, name="lamp_pool_empty", seed=2), (Lamp(40, 50.0, 40.0, (0.4, 0.6)),)
        ),
        EffectScene(
            replace(lamp, name="lamp_walker", seed=1, objects=(walker(-80, 120, 50),)),
            (Lamp(40, 60.0, 10.0, (0.5, 0.3)),),
        ),
        Scene(
            "night_640_walker",
            size=VGA,
            fps=25.0,
            frames=120,
            background_mean=22,
            background_contrast=10.0,
            noise_sigma=5.0,
            objects=(person(-50, 250, 90, grey=50),),
        ),
    ]


def weather_scenes() -> list[Scene | EffectScene]:
    downpour = Rain(drops=260, length=(20.0, 50.0))
    rain_walker = Scene(
        "rain_walker", size=VGA, fps=25.0, frames=120, objects=(person(-50, 220, 90),)
    )
    snow = Snow(flakes=150)
    snow_walker = Scene("snow_walker", frames=120, objects=(walker(-30, 100, 40),))
    cloud = CloudShadow(centre=(-80, 110), velocity=(25.0, 2.0), radius=(120, 90))
    return [
        EffectScene(rain_walker, (downpour,)),
        EffectScene(replace(rain_walker, name="rain_empty", objects=()), (downpour,)),
        EffectScene(
            Scene("drizzle_walker", frames=90, objects=(walker(-30, 100, 40),)),
            (Rain(drops=40),),
        ),
        EffectScene(snow_walker, (snow,)),
        EffectScene(replace(snow_walker, name="snow_empty", objects=()), (snow,)),
        EffectScene(
            replace(snow_walker, name="snow_fine_walker"), (Snow(flakes=250, large_share=0.0),)
        ),
        EffectScene(Scene("clouds_empty", frames=150), (cloud,)),
        EffectScene(
            Scene("clouds_walker", frames=150, objects=(walker(-60, 150, 30),)),
            (cloud,),
        ),
        Scene(
            "sway_640_walkers",
            size=VGA,
            fps=25.0,
            frames=150,
            sway_region=(300, 40, 280, 260),
            objects=(
                person(-80, 180, 80),
                person(760, 300, -70, grey=60),
            ),
        ),
        Scene("sway_wide_empty", frames=120, sway_region=(0, 0, 320, 110)),
    ]


def creeper(speed: float, dark: bool, in_view: bool) -> Scene:
    """A 30x70 object creeping over a textured 640x480 view at 25 fps, darker or lighter
    than the ground, coming in from the left edge or in view from frame 0."""
    name = f"slow_{'inview_' if in_view else ''}{speed:g}pxs_{'dark' if dark else 'light'}"
    x = 300.0 if in_view else -20.0
    grey = 60 if dark else 160
    return Scene(
        name, size=VGA, fps=25.0, frames=200, objects=(walker(x, 300, speed, grey, (30, 70)),)
    )


def object_scenes() -> list[Scene | EffectScene]:
    lorry = Scene(
        "truck_only",
        size=VGA,
        fps=25.0,
        frames=150,
        min_visible_fraction=0.05,
        # Drives in until it fills most of the view, and stays.
        objects=(
            MovingObject(
                (-540, 60), (160.0, 0.0), (520, 360), 40, textured=False, stop=(3.6, 99.0)
            ),
        ),
    )
    bright = replace(lorry.objects[0], intensity=215)
    crowd = (
        person(-50, 60, 60),
        person(690, 90, -70, grey=50),
        person(-240, 200, 90, grey=170),
        person(720, 240, -50, grey=80),
        person(-120, 330, 50, grey=220),
        person(800, 360, -90, grey=30),
        person(200, -100, 10, grey=190, vy=60),
        person(420, 560, -5, grey=60, vy=-70),
    )
    return [
        lorry,
        replace(lorry, name="truck_bright", objects=(bright,)),
        # A cyclist following a lorry into view.
        Scene(
            "truck_cyclist",
            frames=120,
            min_visible_fraction=0.05,
            objects=(
                MovingObject((-200, 60), (70.0, 0.0), (180, 120), 70, textured=False),
                walker(-260, 150, 70, grey=190, size=(36, 30)),
            ),
        ),
        *(
            creeper(speed, dark, in_view)
            for in_view in (False, True)
            for speed, dark in ((4.0, True), (8.0, True), (8.0, False), (16.0, True))
        ),
        Scene(
            "camo_640_walker",
            size=VGA,
            fps=25.0,
            frames=120,
            objects=(person(-50, 200, 80, grey=125),),
        ),
        Scene(
            "camo_slow",
            frames=150,
            objects=(walker(-40, 90, 12, grey=140, size=(40, 30)),),
        ),
        Scene(
            "waiting_dark",
            fps=25.0,
            frames=250,
            seed=3,
            objects=(walker(-30, 100, 50, grey=55, stop=(2.0, 6.0)),),
        ),
        # Waits longer than an object is kept (5 s): it becomes background, then walks on.
        Scene(
            "waiting_8s",
            frames=200,
            objects=(walker(-30, 100, 40, stop=(2.0, 10.0)),),
        ),
        Scene("crowd_640", size=VGA, fps=25.0, frames=150, objects=crowd),
        Scene(
            "crossing_pair",
            frames=100,
            objects=(walker(-20, 100, 50, grey=200), walker(320, 106, -50, grey=50)),
        ),
        # Two who walk side by side, 4 px apart: one blob, one track (README).
        Scene(
            "side_by_side",
            frames=90,
            objects=(walker(-20, 90, 40, grey=190), walker(-20, 138, 40, grey=170)),
        ),
        Scene(
            "small_fast_60fps",
            fps=60.0,
            frames=120,
            objects=(walker(-15, 80, 240, 30, (12, 12), vy=40),),
        ),
    ]


def rate_scenes() -> list[Scene | EffectScene]:
    def crossing(fps: float, frames: int, name: str, size: tuple[int, int] = (320, 240)) -> Scene:
        scale = size[0] // 320
        person = walker(-30 * scale, 100 * scale, 50 * scale, 70, (28 * scale, 44 * scale))
        return Scene(name, size, fps, frames, objects=(person,))

    waits = (walker(-40, 90, 100, grey=60, size=(30, 60), stop=(1.5, 4.5)),)
    return [
        crossing(10.0, 60, "walker_10fps"),
        crossing(60.0, 200, "walker_60fps"),
        crossing(15.0, 90, "walker_640_15fps", size=VGA),
        Scene("waiting_10fps", fps=10.0, frames=70, objects=waits),
        Scene("waiting_60fps", fps=60.0, frames=200, objects=waits),
    ]


LIVE = (
    "box-in-view",
    "slow-dark-in-view",
    "walks-away",
    "pan_walker",
    "rain_walker",
    "slow_16pxs_dark",
)
"""Scenes also run as a live camera activated as it connected sees them (the first frame
learned, no background scan), named ``live_`` and theirs."""


def renamed(scene: Renderable, name: str) -> Renderable:
    if isinstance(scene, EffectScene):
        return replace(scene, world=replace(scene.world, name=name))
    assert isinstance(scene, Scene)
    return replace(scene, name=name)


def knock_while_learning() -> Scene:
    """A knock in the first 20 frames, while a live camera's model learns the scene."""
    return Scene(
        "live_knock_learning",
        frames=90,
        camera_move_frame=10,
        camera_move=(5.0, 2.0),
        objects=(walker(-110, 100, 45),),
    )


def sweep() -> dict[str, SweepScene]:
    """Every scene of the sweep by name, in the order printed."""
    groups: list[tuple[str, Callable[[], Sequence[Renderable]]]] = [
        ("standard", lambda: list(standard_scenes().values())),
        ("in_view", lambda: list(in_view_scenes().values())),
        ("camera", camera_scenes),
        ("light", light_scenes),
        ("weather", weather_scenes),
        ("objects", object_scenes),
        ("rates", rate_scenes),
    ]
    scenes: dict[str, SweepScene] = {}
    for group, make in groups:
        for scene in make():
            if scene.name in scenes:
                raise ValueError(f"two scenes are named {scene.name}")
            scenes[scene.name] = SweepScene(scene, group)
    for name in LIVE:
        live = renamed(scenes[name].scene, f"live_{name}")
        scenes[live.name] = SweepScene(live, "live", scan=False)
    scenes["live_knock_learning"] = SweepScene(knock_while_learning(), "live", scan=False)
    return scenes


def pick(scenes: dict[str, SweepScene], patterns: Sequence[str]) -> dict[str, SweepScene]:
    """The scenes whose name or group matches any of the shell patterns (all without any)."""
    if not patterns:
        return scenes
    return {
        name: item
        for name, item in scenes.items()
        if any(fnmatch.fnmatchcase(name, p) or fnmatch.fnmatchcase(item.group, p) for p in patterns)
    }


# --- running a scene --------------------------------------------------------------------


@dataclass
class Outcome:
    """One method on one scene: the counts, and digests that tell outputs apart exactly."""

    scene: str
    group: str
    method: str
    frames: int
    objects: int
    tp: int = 0
    fp: int = 0
    fn: int = 0
    tracks: int = 0
    """Confirmed track ids reported."""
    events: int = 0
    """Events, as ``vigil analyze`` counts them (ended by ``QUIET_S`` without a detection)."""
    input: str = ""
    """sha1 of every frame's pixels and true boxes: the scene itself."""
    masks: str = ""
    """sha1 of every frame's motion mask (the pipeline's, at detection size)."""
    rows: str = ""
    """sha1 of every detection: frame, track id, box, area, distance and speed."""

    @property
    def counts(self) -> ObjectCounts:
        return ObjectCounts(self.tp, self.fp, self.fn)

    def record(self) -> dict[str, object]:
        """What the baseline keeps of it, under its method and scene."""
        kept = asdict(self)
        del kept["scene"], kept["method"]
        return kept


class Tally:
    """Scores a scene's results frame by frame into an ``Outcome``."""

    def __init__(self, scene: Renderable, group: str, method: str) -> None:
        self.scene = scene
        self.outcome = Outcome(scene.name, group, method, scene.frames, len(scene.objects))
        self.counts = ObjectCounts()
        self.alarms = AlarmLogic(QUIET_S)
        self.track_ids: set[int] = set()
        self.masks = hashlib.sha1(usedforsecurity=False)
        self.rows = hashlib.sha1(usedforsecurity=False)

    def add(self, result: FrameResult) -> None:
        truth = [t.box for t in self.scene.truth(result.index)]
        self.counts.add(truth, [d.box for d in result.detections])
        self.masks.update(result.mask.tobytes())
        for d in result.detections:
            assert d.track_id is not None
            self.track_ids.add(d.track_id)
            # Plain ints and floats: their repr is exact and the same in any NumPy.
            box = [int(v) for v in d.box.as_list()]
            floats = [float(v) for v in (d.area, d.distance_px, d.speed_px_s)]
            self.rows.update(repr((result.index, int(d.track_id), *box, *floats)).encode())
        if self.alarms.update(result.index, result.time_s, result.detections).started:
            self.outcome.events += 1

    def finish(self, input_digest: str) -> Outcome:
        out = self.outcome
        out.tp, out.fp, out.fn = self.counts.tp, self.counts.fp, self.counts.fn
        out.tracks = len(self.track_ids)
        out.input = input_digest
        out.masks = self.masks.hexdigest()
        out.rows = self.rows.hexdigest()
        return out


def render(scene: Renderable) -> tuple[list[Image], str]:
    """The scene's frames, and the digest of them and of their truth."""
    digest = hashlib.sha1(usedforsecurity=False)
    frames = []
    for index in range(scene.frames):
        frame = scene.frame(index)
        digest.update(frame.tobytes())
        digest.update(repr([t.box.as_list() for t in scene.truth(index)]).encode())
        frames.append(frame)
    return frames, digest.hexdigest()


def run_scene(item: SweepScene, methods: Sequence[str]) -> list[Outcome]:
    """Every method on one scene, each with a fresh pipeline, on frames rendered once."""
    cv2.setNumThreads(1)  # The same work in every process, whatever --jobs.
    frames, input_digest = render(item.scene)
    outcomes = []
    for method in methods:
        # OpenCV's KNN draws from OpenCV's random generator, which lives on in the process:
        # without this, its masks depend on what the process ran before.
        cv2.setRNGSeed(OPENCV_SEED)
        tally = Tally(item.scene, item.group, method)
        for result in run_pipeline(method, frames, item.scene.fps, item.scan):
            tally.add(result)
        outcomes.append(tally.finish(input_digest))
    return outcomes


def _run_named(task: tuple[str, tuple[str, ...]]) -> list[Outcome]:
    """``run_scene`` by the scene's name: what a worker process is sent."""
    name, methods = task
    return run_scene(sweep()[name], methods)


def run_sweep(scenes: dict[str, SweepScene], methods: Sequence[str], jobs: int) -> list[Outcome]:
    """Every method on every scene, in ``jobs`` processes; outcomes in the sweep's order,
    method by method. Each scene is rendered and run in one process from scratch, so the
    outcomes do not depend on ``jobs`` or on the order."""
    # Largest first, so no process is left with a long scene at the end.
    names = sorted(scenes, key=lambda n: -_cost(scenes[n].scene))
    if jobs <= 1:
        done = [run_scene(scenes[name], methods) for name in names]
    else:
        tasks = [(name, tuple(methods)) for name in names]
        with multiprocessing.get_context("spawn").Pool(jobs) as pool:
            done = list(pool.imap_unordered(_run_named, tasks))
    by_key = {(o.scene, o.method): o for outcomes in done for o in outcomes}
    return [by_key[name, method] for method in methods for name in scenes]


def _cost(scene: Renderable) -> int:
    return scene.frames * scene.size[0] * scene.size[1]


# --- printing ------------------------------------------------------------------------------


def scene_rows(outcomes: Sequence[Outcome], scenes: dict[str, SweepScene]) -> list[list[Cell]]:
    rows: list[list[Cell]] = []
    for o in outcomes:
        scene = scenes[o.scene].scene
        w, h = scene.size
        counts = o.counts
        rows.append(
            [
                o.scene,
                o.group,
                method_label(o.method),
                f"{w}x{h}@{scene.fps:g}",
                o.frames,
                o.objects,
                counts.detection_rate,
                counts.false_alarm_rate,
                o.tp,
                o.fp,
                o.fn,
                o.tracks,
                o.events,
            ]
        )
    return rows


SCENE_HEADERS = ["scene", "group", "method", "size@fps", "frames", "objects", "DR", "FAR"]
COUNT_HEADERS = ["TP", "FP", "FN", "tracks", "events"]


def pooled_rows(outcomes: Sequence[Outcome], groups: Sequence[str]) -> list[list[Cell]]:
    rows: list[list[Cell]] = []
    methods = list(dict.fromkeys(o.method for o in outcomes))
    for method in methods:
        mine = [o for o in outcomes if o.method == method]
        for group in ["all", *groups]:
            chosen = [o for o in mine if group in ("all", o.group)]
            if not chosen:
                continue
            counts = _pooled(chosen)
            rows.append(
                [
                    method_label(method),
                    group,
                    len(chosen),
                    counts.detection_rate,
                    counts.false_alarm_rate,
                    counts.tp,
                    counts.fp,
                    counts.fn,
                    sum(o.tracks for o in chosen),
                    sum(o.events for o in chosen),
                ]
            )
    return rows


def print_results(outcomes: Sequence[Outcome], scenes: dict[str, SweepScene]) -> None:
    print_table(
        "Per scene",
        SCENE_HEADERS + COUNT_HEADERS,
        scene_rows(outcomes, scenes),
        note=f"    a detection (a confirmed track) matches a true box at IoU >= {DEFAULT_IOU}, "
        "per object per frame;\n    DR = TP/(TP+FN), FAR = FP/(TP+FP) ('-' where undefined); "
        "tracks = track ids reported; events as vigil analyze counts them",
        left=3,
    )
    groups = list(dict.fromkeys(item.group for item in scenes.values()))
    print_table(
        "Pooled (TP, FP, FN summed over the scenes, then the rates)",
        ["method", "group", "scenes", "DR", "FAR", *COUNT_HEADERS],
        pooled_rows(outcomes, groups),
        left=2,
    )


def print_mechanisms(outcomes: Sequence[Outcome]) -> None:
    """What each mechanism switched off costs: pooled figures against the default method's,
    and the scenes it makes worse or better (DR or FAR moved by more than 0.01)."""
    full = {o.scene: o for o in outcomes if o.method == DEFAULT_METHOD}
    rows: list[list[Cell]] = []
    for method in dict.fromkeys(o.method for o in outcomes if WITHOUT in o.method):
        off = [o for o in outcomes if o.method == method]
        on = [full[o.scene] for o in off]
        pooled_off, pooled_on = _pooled(off), _pooled(on)
        judged = [_judged(a.counts, b.counts) for a, b in zip(on, off, strict=True)]
        worse = [o.scene for o, j in zip(off, judged, strict=True) if j == "worse"]
        better = sum(j == "better" for j in judged)
        rows.append(
            [
                method.partition(WITHOUT)[2],
                _delta(pooled_on.detection_rate, pooled_off.detection_rate),
                _delta(pooled_on.false_alarm_rate, pooled_off.false_alarm_rate),
                f"{sum(o.tracks for o in on)} -> {sum(o.tracks for o in off)}",
                len(worse),
                better,
                ", ".join(worse[:4]) + (" ..." if len(worse) > 4 else ""),
            ]
        )
    print_table(
        f"Each mechanism switched off ({DEFAULT_METHOD} -> without it, pooled over the scenes)",
        ["switched off", "DR", "FAR", "tracks", "worse", "better", "worse on (first four)"],
        rows,
        note="    worse / better: scenes whose DR fell or FAR rose (or the reverse) by more "
        "than 0.01",
        left=1,
    )


def _pooled(outcomes: Sequence[Outcome]) -> ObjectCounts:
    return ObjectCounts(
        sum(o.tp for o in outcomes), sum(o.fp for o in outcomes), sum(o.fn for o in outcomes)
    )


def _judged(before: ObjectCounts, after: ObjectCounts) -> str | None:
    """ "worse" where DR fell or FAR rose by more than 0.01, "better" where either moved
    the other way as much, else None (an undefined rate counts as 0)."""
    dr = (after.detection_rate or 0.0) - (before.detection_rate or 0.0)
    far = (after.false_alarm_rate or 0.0) - (before.false_alarm_rate or 0.0)
    if dr < -0.01 or far > 0.01:
        return "worse"
    if dr > 0.01 or far < -0.01:
        return "better"
    return None


# --- the baseline --------------------------------------------------------------------------


Baseline = dict[str, dict[str, dict[str, object]]]
"""method -> scene -> ``Outcome.record()``."""

DIGESTS = ("input", "masks", "rows")


def load_baseline(path: Path) -> Baseline:
    if not path.exists():
        return {}
    data = json.loads(path.read_text())
    return {method: scenes for method, scenes in data.items() if not method.startswith("_")}


def write_baseline(
    path: Path, baseline: Baseline, outcomes: Sequence[Outcome], known: Sequence[str]
) -> None:
    """``baseline`` with this run's outcomes in place of their old records, less any scene no
    longer in the sweep (``known``), one line per scene so that changes diff by scene."""
    for o in outcomes:
        baseline.setdefault(o.method, {})[o.scene] = o.record()
    lines = [
        "{",
        ' "_about": "python bench/scenes.py --method M --write-baseline; see bench/README.md",',
    ]
    methods = sorted(baseline)
    for i, method in enumerate(methods):
        scenes = {name: baseline[method][name] for name in known if name in baseline[method]}
        lines.append(f" {json.dumps(method)}: {{")
        for j, (name, record) in enumerate(scenes.items()):
            comma = "," if j < len(scenes) - 1 else ""
            lines.append(f"  {json.dumps(name)}: {json.dumps(record)}{comma}")
        lines.append(" }" + ("," if i < len(methods) - 1 else ""))
    lines.append("}")
    path.write_text("\n".join(lines) + "\n")


@dataclass
class Change:
    outcome: Outcome
    before: dict[str, object] | None
    """None: the scene is not in the baseline."""

    @property
    def what(self) -> list[str]:
        if self.before is None:
            return ["new"]
        now = self.outcome.record()
        return [key for key in now if now[key] != self.before.get(key)]


def compare(outcomes: Sequence[Outcome], baseline: Baseline) -> list[Change]:
    changes = []
    for o in outcomes:
        before = baseline.get(o.method, {}).get(o.scene)
        change = Change(o, before)
        if change.what:
            changes.append(change)
    return changes


def _delta(before: float | None, now: float | None) -> str:
    if before is None or now is None:
        return f"{fmt(before)} -> {fmt(now)}"
    return f"{fmt(before)} -> {fmt(now)} ({now - before:+.3f})"


def change_rows(changes: Sequence[Change]) -> list[list[Cell]]:
    rows: list[list[Cell]] = []
    for change in changes:
        o, before = change.outcome, change.before
        assert before is not None
        was = ObjectCounts(*(int(str(before[key])) for key in ("tp", "fp", "fn")))
        rows.append(
            [
                o.scene,
                method_label(o.method),
                _delta(was.detection_rate, o.counts.detection_rate),
                _delta(was.false_alarm_rate, o.counts.false_alarm_rate),
                f"{before['tracks']} -> {o.tracks}",
                f"{before['events']} -> {o.events}",
                ", ".join(change.what),
            ]
        )
    return rows


def verdict(outcomes: Sequence[Outcome], changes: Sequence[Change]) -> str:
    """One line: "identical", or how many scenes changed and how."""
    changed = [c for c in changes if c.before is not None]
    new = len(changes) - len(changed)
    compared = len(outcomes) - new
    if not changes:
        return f"identical ({compared} scene runs, counts and digests)"
    parts = [f"{len(changed)} scenes changed (of {compared} compared)"] if compared else []
    only_digests = sum(1 for c in changed if set(c.what) <= set(DIGESTS))
    if only_digests:
        parts.append(f"{only_digests} of them in digests only")
    redrawn = sum(1 for c in changed if "input" in c.what)
    if redrawn:
        parts.append(f"{redrawn} of them because the scene itself changed (input)")
    if new:
        parts.append(f"{new} scene runs not in the baseline")
    return "; ".join(parts)


def print_comparison(outcomes: Sequence[Outcome], baseline: Baseline, path: Path) -> bool:
    """Prints what changed against the baseline; True when nothing did."""
    changes = compare(outcomes, baseline)
    changed = [c for c in changes if c.before is not None]
    if changed:
        print_table(
            f"Changed against the baseline ({_shown(path)})",
            ["scene", "method", "DR", "FAR", "tracks", "events", "what changed"],
            change_rows(changed),
            note="    what changed: counts (tp, fp, fn, tracks, events) and digests (input: "
            "the scene's frames or truth;\n    masks: every frame's motion mask; rows: every "
            "tracked row)",
            left=2,
        )
    print(f"\nAgainst {_shown(path)}: {verdict(outcomes, changes)}")
    return not changes


def _shown(path: Path) -> str:
    try:
        return str(path.resolve().relative_to(REPO_ROOT))
    except ValueError:
        return str(path)


# --- main ----------------------------------------------------------------------------------


def print_list(scenes: dict[str, SweepScene]) -> None:
    rows: list[list[Cell]] = []
    for name, item in scenes.items():
        w, h = item.scene.size
        start = "scan" if item.scan else "first frame"
        rows.append(
            [
                name,
                item.group,
                f"{w}x{h}@{item.scene.fps:g}",
                item.scene.frames,
                len(item.scene.objects),
                start,
            ]
        )
    print_table(
        f"{len(rows)} scenes",
        ["scene", "group", "size@fps", "frames", "objects", "start"],
        rows,
        left=2,
    )


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--method",
        default="adaptive",
        help="method, or comma-separated methods (default: adaptive)",
    )
    parser.add_argument(
        "--scenes",
        default="",
        help="comma-separated shell patterns of scene names or groups (default: all)",
    )
    parser.add_argument("--jobs", type=int, default=1, help="processes (default 1)")
    parser.add_argument(
        "--baseline",
        type=Path,
        default=BASELINE,
        help="baseline file (default bench/scenes_baseline.json)",
    )
    parser.add_argument(
        "--write-baseline", action="store_true", help="write this run's figures into the baseline"
    )
    parser.add_argument(
        "--check",
        action="store_true",
        help="exit with status 1 when anything differs from the baseline",
    )
    parser.add_argument(
        "--off",
        default="",
        help="also run the default method with each of these mechanisms switched off "
        "(comma-separated AdaptiveConfig switches, or 'all'), and print what each is worth",
    )
    parser.add_argument("--list", action="store_true", help="list the scenes and stop")
    args = parser.parse_args(argv)
    mechanisms = list(MECHANISMS) if args.off == "all" else [m for m in args.off.split(",") if m]
    extra = [without(mechanism) for mechanism in mechanisms]
    args.methods = parse_methods(parser, ",".join([args.method, *extra]))
    if extra and DEFAULT_METHOD not in args.methods:
        args.methods.insert(0, DEFAULT_METHOD)
    args.patterns = [p.strip() for p in args.scenes.split(",") if p.strip()]
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    started = time.perf_counter()
    everything = sweep()
    scenes = pick(everything, args.patterns)
    if not scenes:
        print(f"no scene matches {args.scenes!r}; --list shows them", file=sys.stderr)
        return 2
    if args.list:
        print_list(scenes)
        return 0
    print_environment("Vigil scene sweep")
    methods = ", ".join(args.methods)
    print(f"{len(scenes)} of {len(everything)} scenes; {methods}; {args.jobs} process(es)")
    outcomes = run_sweep(scenes, args.methods, args.jobs)
    print_results(outcomes, scenes)
    if any(WITHOUT in method for method in args.methods):
        print_mechanisms(outcomes)
    baseline = load_baseline(args.baseline)
    same = print_comparison(outcomes, baseline, args.baseline)
    if args.write_baseline:
        write_baseline(args.baseline, baseline, outcomes, list(everything))
        print(f"wrote {_shown(args.baseline)} ({', '.join(args.methods)}: {len(scenes)} scenes)")
    frames = sum(item.scene.frames for item in scenes.values())
    print(
        f"\ndone in {time.perf_counter() - started:.0f} s ({len(scenes)} scenes, {frames} frames, "
        f"{len(args.methods)} method(s), --jobs {args.jobs})"
    )
    return 1 if args.check and not same else 0


if __name__ == "__main__":
    sys.exit(main())
