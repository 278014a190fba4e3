"""Speed of Vigil's pipeline: per-stage times, whole-job throughput, blob extraction.

    python bench/bench_pipeline.py [--frames N] [--repeat R] [--threads T] [--data DIR]
                                   [--synthetic] [--paced-frames N] [--long-minutes M]

Prints four tables (see bench/README.md):

(a) the median time of each stage of Vigil's Pipeline, every method, at
    320x240 and 640x480 input;
(b) whole-job throughput (frames/s) of every Vigil method beside two plain
    OpenCV pipelines (MOG2, KNN) doing the same job at full input resolution,
    on frames in memory and including decode from an MJPG AVI;
(c) blob extraction at 640x480: cv2.findContours against
    cv2.connectedComponentsWithStats;
(d) the default method's per-stage time at 320x240 when each frame follows a
    pause, as a live camera's does (40 ms at 25 fps), beside back to back, and
    the OpenCV MOG2 pipeline's whole frame the same two ways;
(e) a long run: the default method's segmentation at 320x240 over the first and
    the last minute of the clip looped for several minutes (a model that slows
    as it ages shows here), beside OpenCV's MOG2 subtractor on the same frames.

All figures are medians. Contenders run round-robin (every contender once,
then every contender again, R times) so a busy machine slows them alike.
"""

from __future__ import annotations

import argparse
import itertools
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import cv2
from _common import (
    Cell,
    add_data_argument,
    find_data_dir,
    fmt,
    make_pipeline,
    median,
    method_label,
    method_names,
    no_data_reason,
    print_environment,
    print_table,
)

from app.analysis.runner import READ_AHEAD
from app.sources.files import open_input
from app.sources.synthetic import standard_scenes
from app.vision.blobs import BlobExtractor
from app.vision.detections import Box, Detection
from app.vision.pipeline import Pipeline, PipelineConfig
from app.vision.tracker import Tracker
from app.vision.types import Image, Mask

SIZES: tuple[tuple[int, int], ...] = ((320, 240), (640, 480))
BLOB_SIZE = (640, 480)
CLIP = Path("clips") / "bgslibrary-video.avi"
SYNTHETIC_SCENE = "crossing"
MEMORY, DECODE = "in memory", "with decode"
MODES = (MEMORY, DECODE)
REFERENCE = "OpenCV MOG2 pipeline"
TARGET_RATIO = 2.0
MIN_AREA = PipelineConfig().min_area
PACED_SIZE = (320, 240)
PAUSE_S = 1 / 25
"""How long a paced frame waits before it is processed: a 25 fps camera's frame period."""
LONG_RUN_SOURCE_FRAMES = 300
"""Source frames of table (e)'s loop, played forwards then backwards (about 20 s of the
real clip): what passes a pixel at one moment of the loop may not pass it again."""

StageSamples = dict[str, list[float]]
"""Stage name -> per-frame durations in seconds ("total" = the frame's sum)."""


# --- footage ------------------------------------------------------------------


@dataclass(frozen=True)
class Footage:
    frames: list[Image]
    fps: float
    description: str


def load_footage(data_arg: Path | None, count: int, synthetic: bool) -> Footage:
    """Real footage when the shared data holds the clip, else the synthetic scene."""
    data_dir = find_data_dir(data_arg)
    clip = data_dir / CLIP if data_dir is not None else None
    if not synthetic and clip is not None and clip.is_file():
        video = open_input(clip)
        frames = list(itertools.islice(video.frames(), count))
        w, h = video.size
        return Footage(frames, video.fps, f"real footage: {clip} ({w}x{h}, {video.fps:g} fps)")
    scene = standard_scenes()[SYNTHETIC_SCENE]
    w, h = scene.size
    if synthetic:
        why = "--synthetic given"
    elif clip is None:
        why = no_data_reason(data_arg)
    else:
        why = f"{clip} is missing"
    return Footage(
        list(scene.frames_iter()),
        scene.fps,
        f"synthetic: standard_scenes()[{SYNTHETIC_SCENE!r}] ({w}x{h}, {scene.fps:g} fps; {why})",
    )


def ping_pong(frames: Sequence[Image], count: int) -> list[Image]:
    """``count`` frames: forwards, backwards, forwards... (no scene cut when it wraps)."""
    cycle = list(frames) + list(frames[-2:0:-1])
    return [cycle[i % len(cycle)] for i in range(count)]


def resized(frames: Iterable[Image], size: tuple[int, int]) -> list[Image]:
    return [cv2.resize(frame, size, interpolation=cv2.INTER_AREA) for frame in frames]


def write_mjpg(frames: Sequence[Image], path: Path, fps: float) -> Path:
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), fps, (w, h))
    if not writer.isOpened():
        raise SystemExit(f"OpenCV cannot write an MJPG AVI at {path}")
    try:
        for frame in frames:
            writer.write(frame)
    finally:
        writer.release()
    return path


# --- the OpenCV baseline --------------------------------------------------------


def contour_detections(mask: Mask, min_area: float = MIN_AREA) -> list[Detection]:
    """Blobs the usual OpenCV way: outer contours, boundingRect, moments."""
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    detections = []
    for contour in contours:
        moments = cv2.moments(contour)
        area = moments["m00"]
        if area < min_area:
            continue
        x, y, w, h = cv2.boundingRect(contour)
        centroid = (moments["m10"] / area, moments["m01"] / area)
        detections.append(Detection(Box(x, y, w, h), centroid, area))
    return detections


def component_detections(
    mask: Mask, min_area: float = MIN_AREA, connectivity: int = 8
) -> list[Detection]:
    """Blobs from cv2.connectedComponentsWithStats (label image, stats, centroids)."""
    count, _, stats, centroids = cv2.connectedComponentsWithStats(mask, connectivity=connectivity)
    return [
        Detection(Box(int(x), int(y), int(w), int(h)), (float(cx), float(cy)), float(area))
        for (x, y, w, h, area), (cx, cy) in zip(stats[1:count], centroids[1:count], strict=True)
        if area >= min_area
    ]


class OpenCVPipeline:
    """Vigil's job done the plain OpenCV way, at full input resolution, same tracker."""

    def __init__(self, subtractor: Callable[[], cv2.BackgroundSubtractor], fps: float) -> None:
        self.subtractor = subtractor()
        self.tracker = Tracker()
        self.fps = fps
        self._index = 0
        self._open = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
        self._close = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))

    def segment(self, frame: Image) -> Mask:
        gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        gray = cv2.GaussianBlur(gray, (3, 3), 0)
        mask = self.subtractor.apply(gray)
        mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, self._open)
        return cv2.morphologyEx(mask, cv2.MORPH_CLOSE, self._close)

    def process(self, frame: Image) -> list[Detection]:
        time_s = self._index / self.fps
        self._index += 1
        return self.tracker.update(contour_detections(self.segment(frame)), time_s)


def mog2() -> cv2.BackgroundSubtractor:
    return cv2.createBackgroundSubtractorMOG2(detectShadows=False)


def knn() -> cv2.BackgroundSubtractor:
    return cv2.createBackgroundSubtractorKNN(detectShadows=False)


# --- contenders and measurement ----------------------------------------------------


class Processor(Protocol):
    def process(self, frame: Image) -> object: ...


@dataclass(frozen=True)
class Contender:
    label: str
    build: Callable[[float], Processor]
    """fps -> a fresh processor."""


def contenders() -> list[Contender]:
    vigil = [
        Contender(f"vigil {method_label(name)}", _vigil_builder(name)) for name in method_names()
    ]
    return [
        *vigil,
        Contender(REFERENCE, lambda fps: OpenCVPipeline(mog2, fps)),
        Contender("OpenCV KNN pipeline", lambda fps: OpenCVPipeline(knn, fps)),
    ]


def _vigil_builder(method: str) -> Callable[[float], Processor]:
    return lambda fps: make_pipeline(method, fps)


def frames_per_second(processor: Processor, source: Callable[[], Iterable[Image]]) -> float:
    """Throughput of one whole job; ``source`` is called inside the timed region."""
    start = time.perf_counter()
    count = 0
    for frame in source():
        processor.process(frame)
        count += 1
    return count / (time.perf_counter() - start)


DECODING = "decoding alone"
"""The with-decode job's reading and decoding, with nothing done to the frames."""


class Nothing:
    def process(self, frame: Image) -> None:
        pass


def stage_samples(pipeline: Pipeline) -> StageSamples:
    samples = {stage: list(values) for stage, values in pipeline.timings.items()}
    samples["total"] = [sum(frame) for frame in zip(*pipeline.timings.values(), strict=True)]
    return samples


@dataclass
class SizeResult:
    """What one input size measured."""

    rates: dict[tuple[str, str], list[float]]
    """(contender label, mode) -> frames/s of each repeat."""
    stages: dict[str, StageSamples]
    """Contender label -> per-stage samples over all in-memory repeats (Vigil only)."""


def measure_size(frames: list[Image], avi: Path, fps: float, repeats: int) -> SizeResult:
    result = SizeResult(defaultdict(list), defaultdict(lambda: defaultdict(list)))
    sources: dict[str, Callable[[], Iterable[Image]]] = {
        MEMORY: lambda: frames,
        DECODE: lambda: open_input(avi).frames(READ_AHEAD),  # As vigil analyze reads.
    }
    for _ in range(repeats):
        result.rates[DECODING, DECODE].append(frames_per_second(Nothing(), sources[DECODE]))
        for contender in contenders():
            for mode in MODES:
                processor = contender.build(fps)
                result.rates[contender.label, mode].append(
                    frames_per_second(processor, sources[mode])
                )
                if mode == MEMORY and isinstance(processor, Pipeline):
                    for stage, values in stage_samples(processor).items():
                        result.stages[contender.label][stage].extend(values)
    return result


# --- blob extraction ----------------------------------------------------------------


def blob_extractors() -> dict[str, Callable[[Mask], list[Detection]]]:
    vigil = BlobExtractor(MIN_AREA)
    return {
        "findContours + boundingRect + moments": contour_detections,
        "connectedComponentsWithStats, 8-connected": component_detections,
        "connectedComponentsWithStats, 4-connected": lambda mask: component_detections(
            mask, connectivity=4
        ),
        "Vigil BlobExtractor (findContours + pixel count)": vigil,
    }


def foreground_masks(frames: Sequence[Image], fps: float) -> list[Mask]:
    """Cleaned full-resolution masks, as the OpenCV MOG2 pipeline sees them."""
    pipeline = OpenCVPipeline(mog2, fps)
    return [pipeline.segment(frame) for frame in frames]


def time_blobs(masks: Sequence[Mask], repeats: int) -> list[list[Cell]]:
    rows: list[list[Cell]] = []
    baseline = None
    for name, extract in blob_extractors().items():
        samples, found = [], 0
        for _ in range(repeats):
            for mask in masks:
                start = time.perf_counter()
                found += len(extract(mask))
                samples.append(time.perf_counter() - start)
        ms = 1000 * median(samples)
        baseline = baseline or ms
        rows.append(
            [name, fmt(ms, 4), fmt(found / (repeats * len(masks)), 2), fmt(ms / baseline, 2)]
        )
    return rows


# --- report ------------------------------------------------------------------------


def print_stage_table(size: tuple[int, int], result: SizeResult, frames: int, repeats: int) -> None:
    labels = list(result.stages)
    stages = list(next(iter(result.stages.values())))
    rows = [
        [stage, *(fmt(1000 * median(result.stages[label][stage]), 3) for label in labels)]
        for stage in stages
    ]
    headers = ["stage", *(label.removeprefix("vigil ") for label in labels)]
    print_table(
        f"(a) Vigil per-stage time, {size[0]}x{size[1]} input, ms per frame (median)",
        headers,
        rows,
        note=f"    {frames} frames x {repeats} repeats per method; Pipeline.timings; "
        f"detection runs at <= {PipelineConfig().detect_width} px wide; "
        "total = median of each frame's sum",
    )


def print_throughput_table(size: tuple[int, int], result: SizeResult, repeats: int) -> None:
    reference = {mode: median(result.rates[REFERENCE, mode]) for mode in MODES}
    rows = []
    for contender in contenders():
        row: list[Cell] = [contender.label]
        for mode in MODES:
            rates = result.rates[contender.label, mode]
            rate = median(rates)
            spread = 100 * (max(rates) - min(rates)) / rate
            row += [fmt(rate, 0), fmt(rate / reference[mode], 2), f"{spread:.0f}%"]
        rows.append(row)
    print_table(
        f"(b) Whole-job throughput, {size[0]}x{size[1]} input, frames/s (median of {repeats})",
        ["pipeline", f"{MEMORY} f/s", "x MOG2", "spread", f"{DECODE} f/s", "x MOG2", "spread"],
        rows,
        note="    in memory = decoded frames already in RAM; with decode = reading "
        "an MJPG AVI from a temp dir as part of the job;\n"
        "    spread = (fastest - slowest run) / median: large on a busy machine",
    )


def print_targets(results: dict[tuple[int, int], SizeResult]) -> None:
    default = f"vigil {method_label(method_names()[0])}"
    print(
        f"\nTarget: {default} >= {TARGET_RATIO:g}x the OpenCV MOG2 pipeline's whole-job "
        "throughput (quality: see bench/accuracy.py)"
    )
    for size, result in results.items():
        for mode in MODES:
            ratio = median(result.rates[default, mode]) / median(result.rates[REFERENCE, mode])
            verdict = "met" if ratio >= TARGET_RATIO else "NOT met"
            print(f"    {size[0]}x{size[1]} {mode:<11}  {ratio:5.2f}x  {verdict}")
    print(
        "Where the with-decode time goes, ms per frame (1000 / the median frames/s); frames are"
        f" decoded up to {READ_AHEAD} ahead by a thread, as vigil analyze reads, so a job takes"
        " about the slower of decoding and its own part (in memory), plus the hand-over:"
    )
    for size, result in results.items():
        decode = 1000 / median(result.rates[DECODING, DECODE])
        parts = []
        for label, name in ((REFERENCE, "MOG2 pipeline"), (default, default)):
            own = 1000 / median(result.rates[label, MEMORY])
            whole = 1000 / median(result.rates[label, DECODE])
            over = whole - max(own, decode)
            parts.append(f"{name} {whole:.3f} (own part {own:.3f}, hand-over {over:+.3f})")
        print(
            f"    {size[0]}x{size[1]}: decoding alone {decode:.3f} (open_input, an MJPG AVI); "
            + "; ".join(parts)
        )


# --- paced frames ----------------------------------------------------------------------


PACED_WARMUP = 30
"""Frames a paced run first processes back to back and leaves out: the model learning
the scene (20 frames) and a few more."""


def run_paced(processor: Processor, frames: Sequence[Image], pause_s: float) -> list[float]:
    """Each frame's processing time (s), every frame after ``pause_s`` of sleep (0: back
    to back), after ``PACED_WARMUP`` frames untimed."""
    for frame in frames[:PACED_WARMUP]:
        processor.process(frame)
    times = []
    for frame in frames[PACED_WARMUP:]:
        if pause_s:
            time.sleep(pause_s)
        start = time.perf_counter()
        processor.process(frame)
        times.append(time.perf_counter() - start)
    return times


def time_paced(frames: Sequence[Image], fps: float, repeats: int) -> list[list[Cell]]:
    """Rows of table (d): the default method's stages, its whole frame, and the MOG2
    pipeline's whole frame; ms back to back, ms paced, and their ratio."""
    stages: dict[float, StageSamples] = {0.0: defaultdict(list), PAUSE_S: defaultdict(list)}
    mog2_frames: dict[float, list[float]] = {0.0: [], PAUSE_S: []}
    for _ in range(repeats):
        for pause_s in (0.0, PAUSE_S):  # Alternating, so a busy spell slows both.
            pipeline = make_pipeline(method_names()[0], fps)
            run_paced(pipeline, frames, pause_s)
            for stage, values in stage_samples(pipeline).items():
                stages[pause_s][stage].extend(values[PACED_WARMUP:])
            mog2_frames[pause_s] += run_paced(OpenCVPipeline(mog2, fps), frames, pause_s)
    rows: list[list[Cell]] = []
    named = [
        (f"vigil {stage}", stages[0.0][stage], stages[PAUSE_S][stage]) for stage in stages[0.0]
    ]
    for label, warm, paced in [*named, (REFERENCE, mog2_frames[0.0], mog2_frames[PAUSE_S])]:
        if not any(warm) and not any(paced):
            continue  # Nothing to do on these frames (morphology, blobs: no motion).
        warm_ms, paced_ms = 1000 * median(warm), 1000 * median(paced)
        rows.append(
            [
                label,
                fmt(warm_ms, 3),
                fmt(paced_ms, 3),
                fmt(paced_ms / warm_ms, 2) if warm_ms else "-",
            ]
        )
    return rows


def time_long_run(frames: Sequence[Image], fps: float, minutes: int) -> list[list[Cell]]:
    """Rows of table (e): the default method's segmentation (its ``apply`` on prepared
    frames) over each frame of ``frames`` looped for ``minutes`` minutes, back to back;
    the median of the first and of the last minute, beside MOG2's ``apply`` on the same
    frames of those minutes (a fresh subtractor, warmed on the frames before them)."""
    pipeline = make_pipeline(method_names()[0], fps)
    prepared = [pipeline.prepare(frame) for frame in frames]
    per_minute = round(60 * fps)
    total = minutes * per_minute
    vigil: list[float] = []
    for index in range(total):
        frame = prepared[index % len(prepared)]
        start = time.perf_counter()
        pipeline.method.apply(frame)
        vigil.append(time.perf_counter() - start)
    rows: list[list[Cell]] = []
    for label, first in (("first minute", 0), (f"minute {minutes}", total - per_minute)):
        subtractor = mog2()
        for index in range(first - PACED_WARMUP, first):
            subtractor.apply(prepared[index % len(prepared)])
        opencv = []
        for index in range(first, first + per_minute):
            start = time.perf_counter()
            subtractor.apply(prepared[index % len(prepared)])
            opencv.append(time.perf_counter() - start)
        vigil_ms = 1000 * median(vigil[first : first + per_minute])
        opencv_ms = 1000 * median(opencv)
        rows.append([label, fmt(vigil_ms, 3), fmt(opencv_ms, 3), fmt(vigil_ms / opencv_ms, 2)])
    return rows


# --- main ---------------------------------------------------------------------------


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--frames",
        type=int,
        default=200,
        help="frames per run (the source is played back and forth to fill it)",
    )
    parser.add_argument("--repeat", type=int, default=7, help="runs per contender (median)")
    parser.add_argument(
        "--threads",
        type=int,
        default=None,
        help="OpenCV threads (cv2.setNumThreads; default: OpenCV's own choice)",
    )
    parser.add_argument(
        "--synthetic",
        action="store_true",
        help="use the synthetic scene even when real footage is present",
    )
    parser.add_argument(
        "--paced-frames",
        type=int,
        default=100,
        help="timed frames per run of table (d), each after a 40 ms pause (0 leaves (d) out)",
    )
    parser.add_argument(
        "--long-minutes",
        type=int,
        default=10,
        help="minutes of video (at the clip's frame rate) in table (e)'s long run (0 leaves "
        "(e) out)",
    )
    add_data_argument(parser)
    args = parser.parse_args(argv)
    if args.frames < 2 or args.repeat < 1 or (args.threads is not None and args.threads < 0):
        parser.error("--frames must be >= 2, --repeat >= 1 and --threads >= 0")
    if args.paced_frames < 0:
        parser.error("--paced-frames must be >= 0")
    if args.long_minutes == 1 or args.long_minutes < 0:
        parser.error("--long-minutes must be 0 or at least 2")
    return args


def main(argv: Sequence[str] | None = None) -> None:
    args = parse_args(argv)
    started = time.perf_counter()
    if args.threads is not None:
        cv2.setNumThreads(args.threads)
    footage = load_footage(args.data, args.frames, args.synthetic)
    sequence = ping_pong(footage.frames, args.frames)
    print_environment("Vigil pipeline benchmark")
    print(
        f"frames: {footage.description}; {len(footage.frames)} source frames played "
        f"back and forth to {args.frames}, resized to each input size"
    )
    results: dict[tuple[int, int], SizeResult] = {}
    with tempfile.TemporaryDirectory(prefix="vigil-bench-") as tmp:
        for size in SIZES:
            frames = resized(sequence, size)
            avi = write_mjpg(frames, Path(tmp) / f"{size[0]}x{size[1]}.avi", footage.fps)
            results[size] = measure_size(frames, avi, footage.fps, args.repeat)
    for size, result in results.items():
        print_stage_table(size, result, args.frames, args.repeat)
    for size, result in results.items():
        print_throughput_table(size, result, args.repeat)
    print_targets(results)
    masks = foreground_masks(resized(sequence, BLOB_SIZE), footage.fps)
    print_table(
        f"(c) Blob extraction, {BLOB_SIZE[0]}x{BLOB_SIZE[1]} masks of the OpenCV MOG2 "
        "pipeline, ms per frame (median)",
        ["extractor", "ms", "blobs/frame", "x findContours"],
        time_blobs(masks, args.repeat),
        note=f"    blobs/frame = detections of at least {MIN_AREA:g} px",
    )
    if args.paced_frames:
        paced = resized(ping_pong(footage.frames, PACED_WARMUP + args.paced_frames), PACED_SIZE)
        print_table(
            f"(d) Paced frames, {PACED_SIZE[0]}x{PACED_SIZE[1]}: each frame after a "
            f"{1000 * PAUSE_S:g} ms pause, as a 25 fps camera waits, ms per frame (median)",
            ["stage", "back to back", "paced", "x back to back"],
            time_paced(paced, footage.fps, args.repeat),
            note=f"    {args.paced_frames} frames x {args.repeat} repeats each way, after "
            f"{PACED_WARMUP} untimed; a paced frame finds code and data gone cold "
            "(bench/README.md)",
        )
    if args.long_minutes:
        source = load_footage(args.data, LONG_RUN_SOURCE_FRAMES, args.synthetic)
        loop = ping_pong(source.frames, 2 * len(source.frames) - 2)
        long_run = resized(loop, PACED_SIZE)
        print_table(
            f"(e) Long run, {PACED_SIZE[0]}x{PACED_SIZE[1]}: segmentation over the first and "
            f"the last minute of {args.long_minutes} minutes of the clip looped, ms per frame "
            "(median), back to back",
            ["minute", f"vigil {method_label(method_names()[0])}", "OpenCV MOG2", "x MOG2"],
            time_long_run(long_run, source.fps, args.long_minutes),
            note=f"    {len(loop)} frames looped (the first {len(source.frames)} of the "
            "footage, forwards then backwards); the same frames for both; a model "
            "that slows as it ages shows as a later minute's rise",
        )
    print(f"\ndone in {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
