"""The demo camera's street scene: what a frame costs, and what the default method finds.

    python bench/bench_demo_scene.py [--loops N] [--no-detect]

Prints:

(a) the one-off costs in this process: painting the street, then drawing every sprite
    the loop needs (a pose of a passer-by is drawn when first shown, so a demo camera's
    first loop pays it, spread over the loop), and the memory the sprites then hold;
(b) a frame after that, as the demo camera renders it (`DemoSource.read`): the median
    and 95th percentile over N loops, wall time and the thread's CPU time;
(c) unless --no-detect: the default pipeline on N loops of the scene from a fresh start,
    as a demo camera started at frame 0 sees them, loop by loop: DR and FAR (per object
    per frame, IoU 0.3; a detection lying on an object less than half in view counts
    neither way), per passer-by the frames found, its median IoU and median speed
    error (tracks older than 6 frames); detections on frames with nothing in view; and
    the times alarms start under the server's default quiet and gap seconds. A false
    alarm is put down to the passer-by most of its box lies on (a piece of someone
    reported as an object of its own), or to no one.
"""

from __future__ import annotations

import argparse
import gc
import statistics
import time
from collections import Counter, defaultdict

from _common import print_environment, print_table

from app.analysis.metrics import DEFAULT_IOU, ObjectCounts, match_boxes
from app.core.config import Settings
from app.events.alarm import AlarmLogic
from app.sources.demo_scene import StreetScene
from app.sources.demo_sprites import Sprite
from app.sources.demo_street import paint_street
from app.sources.live import DemoSource, demo_scene
from app.sources.synthetic import TruthObject
from app.vision.detections import Box
from app.vision.pipeline import Pipeline, PipelineConfig

SETTLED_FRAMES = 6


def one_off_costs() -> None:
    started = time.perf_counter()
    paint_street()
    painted = time.perf_counter() - started
    scene = demo_scene()  # Painted once more, here, for this process's cache.
    started = time.perf_counter()
    for index in range(scene.frames):
        scene.frame(index)
    first_loop = time.perf_counter() - started
    sprites = [o for o in gc.get_objects() if isinstance(o, Sprite)]
    held = sum(s.colour.nbytes + s.keep.nbytes for s in sprites) / 1e6
    print(
        f"\n(a) street painted in {painted * 1e3:.0f} ms; the first loop "
        f"({scene.frames} frames, each sprite drawn when first shown) in {first_loop:.2f} s; "
        f"{len(sprites)} sprites kept, {held:.1f} MB"
    )


def frame_costs(loops: int) -> None:
    source = DemoSource()
    frames = source.scene.frames
    wall, cpu = [], []
    for _ in range(loops * frames):
        wall0, cpu0 = time.perf_counter(), time.thread_time()
        source.read()
        cpu.append(time.thread_time() - cpu0)
        wall.append(time.perf_counter() - wall0)
    rows = [
        [name, f"{statistics.median(v) * 1e3:.2f}", f"{_percentile(v, 95) * 1e3:.2f}"]
        for name, v in (("wall", wall), ("thread CPU", cpu))
    ]
    width, height = source.scene.size
    title = f"(b) a frame of the demo scene, {width}x{height}, {loops} loop(s) of {frames}, ms"
    print_table(title, ["time", "median", "p95"], rows)


def detection(scene: StreetScene, loops: int) -> None:
    pipeline = Pipeline(PipelineConfig(), fps=scene.fps)
    defaults = Settings.model_fields
    alarms = AlarmLogic(defaults["quiet_s"].default, defaults["alarm_gap_s"].default)
    starts: list[float] = []
    age: Counter[int | None] = Counter()
    for loop in range(loops):
        counts = ObjectCounts()
        shown, found, extra = Counter[int](), Counter[int](), Counter[int | None]()
        ious, speed_errors = defaultdict(list), defaultdict(list)
        on_empty = 0
        for index in range(scene.frames):
            frame_no = loop * scene.frames + index
            result = pipeline.process(scene.frame(index))
            if alarms.update(frame_no, frame_no / scene.fps, result.detections).started:
                starts.append(frame_no / scene.fps)
            if not scene.in_view(index):
                on_empty += len(result.detections)
            found_here = [d for d in result.detections if not scene.on_partly_visible(index, d.box)]
            truth = scene.truth(index)
            boxes = [d.box for d in found_here]
            counts.add([t.box for t in truth], boxes)
            for true in truth:
                shown[true.object_index] += 1
                ious[true.object_index].append(max((true.box.iou(b) for b in boxes), default=0))
            for d in found_here:
                age[d.track_id] += 1
            pairs = match_boxes([t.box for t in truth], boxes, DEFAULT_IOU)
            matched = {d_index for _, d_index in pairs}
            for d_index, box in enumerate(boxes):
                if d_index not in matched:  # A false alarm: on whom, if on anyone?
                    extra[_under(box, truth)] += 1
            for t_index, d_index in pairs:
                true, seen = truth[t_index], found_here[d_index]
                found[true.object_index] += 1
                if age[seen.track_id] > SETTLED_FRAMES:
                    speed_errors[true.object_index].append(
                        abs(seen.speed_px_s - true.speed_px_s) / true.speed_px_s
                    )
        empty = sum(not scene.in_view(i) for i in range(scene.frames))
        title = (
            f"(c) the default method ({pipeline.config.method}), loop {loop + 1}: "
            f"DR {counts.detection_rate:.3f}, FAR {counts.false_alarm_rate:.3f} (TP "
            f"{counts.tp}, FP {counts.fp}, FN {counts.fn}); {on_empty} detections on the "
            f"{empty} frames with nothing in view"
        )
        rows = [
            [
                k,
                _what(scene, k),
                f"{found[k]}/{shown[k]}",
                f"{statistics.median(ious[k]):.2f}",
                f"{statistics.median(speed_errors[k]):.3f}" if speed_errors[k] else "-",
                extra[k],
            ]
            for k in sorted(shown)
        ]
        rows.append(["-", "on no one", "", "", "", extra[None]])
        headers = ["#", "passer-by", "found", "median IoU", "speed error", "false alarms"]
        print_table(title, headers, rows, left=2)
    print("\nalarms started at (s): " + ", ".join(f"{s:.1f}" for s in starts))


def _under(box: Box, truth: list[TruthObject]) -> int | None:
    """The object most of ``box`` lies on (a piece of it reported on its own), if any."""
    for true in truth:
        t = true.box
        w = min(box.x + box.w, t.x + t.w) - max(box.x, t.x)
        h = min(box.y + box.h, t.y + t.h) - max(box.y, t.y)
        if w > 0 and h > 0 and 2 * w * h >= box.area:
            return true.object_index
    return None


def _what(scene: StreetScene, index: int) -> str:
    passing = scene.passings[index]
    kind = type(passing.look).__name__.lower()
    way = "crossing the road" if passing.start[1] != passing.end[1] else "going"
    direction = "left" if passing.end[0] < passing.start[0] else "right"
    return f"{kind} {way} {direction} at {passing.start_s:.1f} s"


def _percentile(values: list[float], share: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(share / 100 * (len(ordered) - 1)))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--loops", type=int, default=2, help="loops timed and scored (2)")
    parser.add_argument("--no-detect", action="store_true", help="time the rendering only")
    args = parser.parse_args()
    print_environment("Demo scene")
    one_off_costs()
    frame_costs(args.loops)
    if not args.no_detect:
        detection(demo_scene(), args.loops)


if __name__ == "__main__":
    main()
