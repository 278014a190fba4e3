"""Detection quality of every method: real footage (pixels) and synthetic scenes (objects).

    python bench/accuracy.py [--warmup 20] [--methods a,b] [--data DIR]

Prints (see bench/README.md):

1. CDnet pixel metrics (precision, recall, F-measure) over all scored frames
   and after a warm-up, on cdnet-traffic, cdnet-fall and Wallflower
   WavingTrees frame 247, with ROI and temporal ROI honoured;
2. per synthetic scene: object Detection Rate and False Alarm Rate, the
   median relative speed error (single-object scenes) and the detections
   (scenes without objects);
3. a one-line-per-method summary.

The real-footage part is skipped, with the reason printed, when the shared
data folder is absent.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from statistics import fmean

from _common import (
    Cell,
    add_data_argument,
    find_data_dir,
    fmt,
    median,
    method_label,
    method_names,
    no_data_reason,
    parse_methods,
    print_environment,
    print_table,
    run_pipeline,
)

from app.analysis.metrics import DEFAULT_IOU, ObjectCounts, PixelCounts, match_boxes
from app.analysis.truth import Truth, load_truth
from app.sources.files import open_input
from app.sources.synthetic import Scene, in_view_scenes, standard_scenes
from app.vision.motion import DEFAULT_METHOD
from app.vision.preprocess import to_size
from app.vision.types import Image, Mask

REFERENCE = "knn"
"""The quality bar of the target: the default method must match OpenCV's KNN."""
SPEED_FROM_FRAME = 10
"""Speed errors are taken after this frame (the velocity fit needs a few sightings)."""


# --- real footage: CDnet pixel metrics ------------------------------------------------


@dataclass(frozen=True)
class RealSet:
    name: str
    input: str
    """Frames, relative to the data folder."""
    truth: str
    """A CDnet sequence folder or a single mask image, relative to the data folder."""


REAL_SETS = (
    RealSet("cdnet-traffic", "cdnet-traffic/input", "cdnet-traffic"),
    RealSet("cdnet-fall", "cdnet-fall/input", "cdnet-fall"),
    RealSet(
        "wallflower-247",
        "wallflower-waving-trees/input",
        "wallflower-waving-trees/hand_segmented_00247.png",
    ),
)


@dataclass
class LoadedSet:
    """A real set decoded once and shared by every method."""

    name: str
    frames: list[Image]
    fps: float
    labels: dict[int, Mask]
    """0-based frame index -> CDnet label image, scored frames only."""
    roi: Mask | None


@dataclass
class PixelScore:
    all_frames: PixelCounts = field(default_factory=PixelCounts)
    warm: PixelCounts = field(default_factory=PixelCounts)
    frames_all: int = 0
    frames_warm: int = 0


def load_set(data_dir: Path, real_set: RealSet) -> LoadedSet:
    video = open_input(data_dir / real_set.input)
    truth: Truth = load_truth(data_dir / real_set.truth, video.frame_numbers)
    labels = {index: mask for index in truth.frames if (mask := truth.mask(index)) is not None}
    frames = list(video.frames())
    if video.skipped:  # Labels go by decode index: the frames after a gap would be misread.
        raise SystemExit(f"{real_set.name}: frames {video.skipped} do not decode")
    return LoadedSet(real_set.name, frames, video.fps, labels, truth.roi)


def score_pixels(loaded: LoadedSet, method: str, warmup: int, scan: bool) -> PixelScore:
    score = PixelScore()
    for result in run_pipeline(method, loaded.frames, loaded.fps, scan):
        label = loaded.labels.get(result.index)
        if label is None:
            continue
        size = (label.shape[1], label.shape[0])
        mask = to_size(result.mask, size)
        roi = to_size(loaded.roi, size) if loaded.roi is not None else None
        score.all_frames.add(mask, label, roi)
        score.frames_all += 1
        if result.index >= warmup:
            score.warm.add(mask, label, roi)
            score.frames_warm += 1
    return score


def pixel_rows(
    loaded: LoadedSet,
    methods: Sequence[str],
    warmup: int,
    scan: bool,
    f_measures: dict[str, list[float]],
) -> list[list[Cell]]:
    rows: list[list[Cell]] = []
    for method in methods:
        score = score_pixels(loaded, method, warmup, scan)
        if score.frames_warm:
            f_measures[method].append(score.warm.f_measure)
        rows.append(
            [
                loaded.name,
                method_label(method),
                *_pixel_cells(score.all_frames, score.frames_all),
                *_pixel_cells(score.warm, score.frames_warm),
            ]
        )
    return rows


def _pixel_cells(counts: PixelCounts, frames: int) -> list[Cell]:
    if not frames:
        return [0, None, None, None]
    return [frames, counts.precision, counts.recall, counts.f_measure]


def report_real(
    data_arg: Path | None, methods: Sequence[str], warmup: int, scan: bool
) -> dict[str, float]:
    """Prints the pixel table; returns each method's mean F-measure after warm-up."""
    data_dir = find_data_dir(data_arg)
    if data_dir is None:
        print(f"\n1. Real footage: SKIPPED - {no_data_reason(data_arg)}")
        return {}
    f_measures: dict[str, list[float]] = {method: [] for method in methods}
    rows: list[list[Cell]] = []
    for real_set in REAL_SETS:
        if not (data_dir / real_set.input).is_dir():
            print(f"\n(skipping {real_set.name}: {data_dir / real_set.input} is missing)")
            continue
        rows += pixel_rows(load_set(data_dir, real_set), methods, warmup, scan, f_measures)
    metric = ["P", "R", "F"]
    print_table(
        f"1. CDnet pixel metrics on real footage ({data_dir})",
        ["set", "method", "frames", *metric, f"frames>={warmup}", *metric],
        rows,
        note="    P = precision, R = recall, F = F-measure; only pixels labelled "
        "0 or 255 inside ROI and temporal ROI are scored; left: every scored "
        f"frame, right: from frame {warmup} (0-based) on",
        left=2,
    )
    return {method: fmean(values) for method, values in f_measures.items() if values}


# --- synthetic scenes: object metrics ------------------------------------------------------


@dataclass
class ObjectScore:
    counts: ObjectCounts = field(default_factory=ObjectCounts)
    speed_errors: list[float] = field(default_factory=list)
    detections: int = 0


def score_scene(scene: Scene, frames: Sequence[Image], method: str, scan: bool) -> ObjectScore:
    score = ObjectScore()
    single = len(scene.objects) == 1
    for result in run_pipeline(method, frames, scene.fps, scan):
        truth = scene.truth(result.index)
        truth_boxes = [t.box for t in truth]
        found = [d.box for d in result.detections]
        score.counts.add(truth_boxes, found)
        score.detections += len(found)
        if single and result.index > SPEED_FROM_FRAME:
            for t, d in match_boxes(truth_boxes, found, DEFAULT_IOU):
                speed = truth[t].speed_px_s
                if not speed:  # Standing still: no relative error to take.
                    continue
                score.speed_errors.append(abs(result.detections[d].speed_px_s - speed) / speed)
    return score


@dataclass
class MethodTotals:
    """One method summed over every synthetic scene."""

    counts: ObjectCounts = field(default_factory=ObjectCounts)
    speed_errors: list[float] = field(default_factory=list)
    empty_detections: int = 0

    def include(self, scene: Scene, score: ObjectScore) -> None:
        self.counts.tp += score.counts.tp
        self.counts.fp += score.counts.fp
        self.counts.fn += score.counts.fn
        self.speed_errors += score.speed_errors
        if not scene.objects:
            self.empty_detections += score.detections


def scene_row(scene: Scene, method: str, score: ObjectScore) -> list[Cell]:
    counts = score.counts
    speed = median(score.speed_errors) if len(scene.objects) == 1 else None
    empty = score.detections if not scene.objects else None
    return [
        scene.name,
        method_label(method),
        counts.detection_rate,
        counts.false_alarm_rate,
        counts.tp,
        counts.fp,
        counts.fn,
        speed,
        empty,
    ]


def report_synthetic(
    title: str, scenes: dict[str, Scene], methods: Sequence[str], scan: bool
) -> dict[str, MethodTotals]:
    totals = {method: MethodTotals() for method in methods}
    rows: list[list[Cell]] = []
    for scene in scenes.values():
        frames = list(scene.frames_iter())
        for method in methods:
            score = score_scene(scene, frames, method, scan)
            totals[method].include(scene, score)
            rows.append(scene_row(scene, method, score))
    for method in methods:
        pooled = totals[method].counts
        rows.append(
            [
                "pooled",
                method_label(method),
                pooled.detection_rate,
                pooled.false_alarm_rate,
                pooled.tp,
                pooled.fp,
                pooled.fn,
                None,
                None,
            ]
        )
    print_table(
        title,
        ["scene", "method", "DR", "FAR", "TP", "FP", "FN", "speed err", "detections"],
        rows,
        note=f"    a detection matches a true box at IoU >= {DEFAULT_IOU}; DR = TP/(TP+FN),"
        " FAR = FP/(TP+FP); speed err = median |measured - true| / true speed, "
        f"single-object scenes, frames > {SPEED_FROM_FRAME}; detections = on scenes "
        "with no objects ('-' = not applicable)",
        left=2,
    )
    return totals


# --- summary and main ------------------------------------------------------------------------


def report_summary(
    methods: Sequence[str], real_f: dict[str, float], totals: dict[str, MethodTotals], warmup: int
) -> None:
    rows: list[list[Cell]] = []
    for method in methods:
        total = totals[method]
        rows.append(
            [
                method_label(method),
                real_f.get(method),
                total.counts.detection_rate,
                total.counts.false_alarm_rate,
                median(total.speed_errors),
                total.empty_detections,
            ]
        )
    print_table(
        "3. Summary per method",
        ["method", f"real F (>= {warmup})", "DR", "FAR", "speed err", "detections on empty"],
        rows,
        note="    real F = mean F-measure after warm-up over the real sets ('-' when "
        "skipped); DR, FAR pooled over every synthetic scene; speed err = median "
        "over single-object scenes",
    )


def print_quality_target(real_f: dict[str, float], totals: dict[str, MethodTotals]) -> None:
    """The quality half of the target: the default method at least as good as KNN."""
    print(
        f"\nTarget: {method_label(DEFAULT_METHOD)} at {REFERENCE} quality or better "
        "(speed: see bench/bench_pipeline.py)"
    )
    if DEFAULT_METHOD not in totals or REFERENCE not in totals:
        print(f"    not judged: run with both {DEFAULT_METHOD} and {REFERENCE} in --methods")
        return
    ours, theirs = totals[DEFAULT_METHOD].counts, totals[REFERENCE].counts
    checks = [
        ("real F after warm-up", real_f.get(DEFAULT_METHOD), real_f.get(REFERENCE), True),
        ("synthetic DR", ours.detection_rate, theirs.detection_rate, True),
        ("synthetic FAR", ours.false_alarm_rate, theirs.false_alarm_rate, False),
    ]
    for name, mine, reference, higher_is_better in checks:
        print(
            f"    {name:<21} {fmt(mine)} vs {fmt(reference)}  "
            f"{_verdict(mine, reference, higher_is_better)}"
        )


def _verdict(mine: float | None, reference: float | None, higher_is_better: bool) -> str:
    if mine is None or reference is None:
        return "not measured"
    better = mine >= reference if higher_is_better else mine <= reference
    return "met" if better else "NOT met"


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--warmup",
        type=int,
        default=20,
        help="frames a model may learn before the 'after warm-up' scores",
    )
    parser.add_argument(
        "--methods", default=",".join(method_names()), help="comma-separated methods (default: all)"
    )
    parser.add_argument(
        "--no-background-scan",
        dest="background_scan",
        action="store_false",
        help="start each method from the first frame, as a live camera does",
    )
    add_data_argument(parser)
    args = parser.parse_args(argv)
    args.methods = parse_methods(parser, args.methods)
    return args


def main(argv: Sequence[str] | None = None) -> None:
    args = parse_args(argv)
    started = time.perf_counter()
    print_environment("Vigil accuracy")
    scan = args.background_scan
    print(
        "background scan: "
        + ("on (as vigil analyze runs)" if scan else "off (as a live camera starts)")
    )
    real_f = report_real(args.data, args.methods, args.warmup, scan)
    totals = report_synthetic(
        "2. Synthetic scenes (app.sources.synthetic.standard_scenes), per object per frame",
        standard_scenes(),
        args.methods,
        scan,
    )
    report_synthetic(
        "2b. Objects in view at frame 0 (app.sources.synthetic.in_view_scenes): what the "
        "background scan is for; not part of the target",
        in_view_scenes(),
        args.methods,
        scan,
    )
    report_summary(args.methods, real_f, totals, args.warmup)
    print_quality_target(real_f, totals)
    print(f"\ndone in {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
