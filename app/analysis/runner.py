"""Offline mode: analyse a recorded video frame by frame (`vigil analyze`)."""

from __future__ import annotations

import contextlib
import functools
import itertools
import math
import statistics
import time
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import app
from app.analysis.outputs import AnnotatedVideo, TracksCsv, write_image, write_json
from app.analysis.report_html import write_report_html
from app.analysis.scoring import Scorer
from app.analysis.truth import Truth, load_truth
from app.events.alarm import AlarmLogic, MotionEvent
from app.sources.files import (
    MIN_FRAMES,
    SINGLE_PICTURE,
    InputError,
    VideoInput,
    open_input,
)
from app.vision.annotate import Annotator, difference_picture
from app.vision.calibration import GroundPlane
from app.vision.detections import Detection
from app.vision.pipeline import FrameResult, Pipeline, PipelineConfig
from app.vision.preprocess import Downscale, to_size
from app.vision.scene_background import (
    LEAST_SAMPLES,
    EvenSample,
    SceneBackground,
    estimate_scene_background,
)
from app.vision.types import GrayImage, Image

Progress = Callable[[int, int | None], None]
"""Called with (frames done, frames expected or None) as the analysis goes."""
MAX_FRAMES_NAMED = 10
"""Skipped frames a warning names one by one (report.json lists them all)."""
FrameObserver = Callable[[Image], None]
"""Called with each annotated frame (for a live view of a running analysis)."""
READ_AHEAD = 4
"""Frames decoded ahead by a thread while the current one is analysed (``read_ahead``)."""
BACKGROUND_SCAN_S = 30.0
"""Seconds of video, from the start, that the background scan samples."""
BACKGROUND_SCAN_FRAMES = 1500
"""The most frames the background scan reads, whatever the frame rate."""
BACKGROUND_SAMPLES = 32
"""Frames the scan keeps, at least (``EvenSample``: fewer than twice as many)."""
BACKGROUND_SCAN_BYTES = 128 * 2**20
"""What the kept frames may take, at most, but never fewer than ``LEAST_SAMPLES`` (4K
frames detected at full size: 10 to 19 of them)."""


@dataclass(frozen=True)
class AnalysisOptions:
    pipeline: PipelineConfig = field(default_factory=PipelineConfig)
    masks: bool = False
    truth: Path | None = None
    calibration: GroundPlane | None = None
    fps: float | None = None
    """Frame rate of a folder of frames (a video's own rate is read from it)."""
    max_pixels: int | None = None
    """Largest frame (width x height) accepted, checked from the header before decoding."""
    quiet_s: float = 1.0
    """Seconds without motion that end an event."""
    input_name: str | None = None
    """How the report names the input (an upload's own file name); default its path."""
    background_scan: bool = True
    """Estimate the empty scene from the video's first ``BACKGROUND_SCAN_S`` seconds before
    detecting (``app.vision.scene_background``), rather than learn it from the first frame
    as a live camera must."""


FITTING_ROWS = 3
"""A track's first rows, whose speeds are fitted to two to four sightings: its largest
speed is taken after them (where it has more), since one step of a pixel at detection
size in so few, at the frame's edge as it comes in, can double the speed."""


@dataclass
class _TrackSummary:
    track_id: int
    first_frame: int
    last_frame: int
    first_time_s: float
    last_time_s: float
    distance_px: float = 0.0
    speeds: list[float] = field(default_factory=list)
    distance_m: float = 0.0
    speeds_m_s: list[float] = field(default_factory=list)
    last_ground: tuple[float, float] | None = None
    ranges_m: list[float] = field(default_factory=list)
    path: list[tuple[float, float]] = field(default_factory=list)
    times: list[float] = field(default_factory=list)

    def add(self, frame: int, time_s: float, d: Detection) -> None:
        self.last_frame, self.last_time_s = frame, time_s
        self.times.append(time_s)
        self.distance_px += d.distance_px
        self.speeds.append(d.speed_px_s)
        self.path.append(d.centroid)
        if d.ground_xy_m is not None:
            if self.last_ground is not None:
                self.distance_m += math.dist(d.ground_xy_m, self.last_ground)
            self.last_ground = d.ground_xy_m
            if d.speed_m_s is not None:
                self.speeds_m_s.append(d.speed_m_s)
            if d.range_m is not None:
                self.ranges_m.append(d.range_m)

    def as_dict(self) -> dict[str, Any]:
        # Over every row tracks.csv has for the track: a track is reported once confirmed,
        # its velocity fitted to the sightings before, so its first row's speed is one.
        # Its speeds from its fourth row on, where it has them (``FITTING_ROWS``).
        fitted = self.speeds[FITTING_ROWS:] or self.speeds
        out: dict[str, Any] = {
            "track_id": self.track_id,
            "first_frame": self.first_frame,
            "last_frame": self.last_frame,
            "frames": len(self.speeds),
            "duration_s": round(self.last_time_s - self.first_time_s, 4),
            "distance_px": round(self.distance_px, 2),
            "mean_speed_px_s": round(statistics.fmean(fitted), 3),
            "max_speed_px_s": round(max(fitted), 3),
        }
        if self.speeds_m_s:
            mean_m_s = statistics.fmean(self.speeds_m_s)
            out.update(
                {
                    "distance_m": round(self.distance_m, 3),
                    "mean_speed_m_s": round(mean_m_s, 3),
                    "mean_speed_km_h": round(mean_m_s * 3.6, 2),
                    "first_range_m": round(self.ranges_m[0], 2),
                    "last_range_m": round(self.ranges_m[-1], 2),
                }
            )
        return out


def analyze(
    input_path: Path,
    out_dir: Path,
    options: AnalysisOptions | None = None,
    progress: Progress | None = None,
    on_frame: FrameObserver | None = None,
) -> dict[str, Any]:
    """Analyse ``input_path`` into ``out_dir``; returns the report (also report.json).

    Raises InputError or TruthError (both ValueError) with a one-line reason
    when the input or the truth cannot be used.
    """
    options = options or AnalysisOptions()
    source = open_input(input_path, options.fps, options.max_pixels)
    check_min_area(options.pipeline.min_area, source.size)
    truth = load_truth(options.truth, source.frame_numbers) if options.truth else None
    if truth is not None:
        truth.check_size(source.size)
    out_dir.mkdir(parents=True, exist_ok=True)
    remove_earlier_outputs(out_dir)
    (out_dir / "snapshots").mkdir(exist_ok=True)
    (out_dir / "differences").mkdir(exist_ok=True)
    if options.masks:
        (out_dir / "masks").mkdir(exist_ok=True)
    return _Analysis(source, out_dir, options, truth, progress, on_frame).run()


def check_min_area(min_area: float, size: tuple[int, int]) -> None:
    """InputError where no object in a frame of ``size`` could cover ``min_area``:
    detection would be quietly off."""
    width, height = size
    if min_area > width * height:
        raise InputError(
            f"min_area {min_area:g} px is more than a frame of this video holds "
            f"({width}x{height} = {width * height:,} px): no object could be detected"
        )


EARLIER_PICTURES = (
    ("snapshots", "event-[0-9][0-9][0-9][0-9]*.jpg"),
    ("differences", "event-[0-9][0-9][0-9][0-9]*.jpg"),
    ("masks", "[0-9][0-9][0-9][0-9][0-9][0-9]*.png"),
)
"""Pictures an earlier analysis wrote into an output folder that this one may not write
again: (folder, name pattern)."""


def remove_earlier_outputs(out_dir: Path) -> None:
    """Remove what an earlier analysis into ``out_dir`` left that this one would not
    overwrite (its events' snapshots, its masks, their scores by ``vigil evaluate``), so
    that the folder holds one run's outputs only. Other files are the user's, and stay."""
    for folder, pattern in EARLIER_PICTURES:
        for path in (out_dir / folder).glob(pattern):
            if path.is_file():
                path.unlink()
        # Emptied, it goes too: a masks/ folder says the analysis wrote masks.
        with contextlib.suppress(OSError):
            (out_dir / folder).rmdir()
    (out_dir / "evaluation.json").unlink(missing_ok=True)


@dataclass(frozen=True)
class BackgroundScan:
    """What the background scan read, and the scene it found (None: too few frames)."""

    frames: int
    samples: int
    scene: SceneBackground | None
    seconds: float

    def as_dict(self) -> dict[str, Any]:
        return {
            "frames": self.frames,
            "samples": self.samples,
            "used": self.scene is not None,
            "view_changed": self.scene is not None and self.scene.view_changed,
            "seconds": round(self.seconds, 3),
        }


def scan_background(pipeline: Pipeline, frames: Iterable[Image], fps: float) -> BackgroundScan:
    """Sample the first ``BACKGROUND_SCAN_S`` seconds of ``frames`` evenly and have
    ``pipeline`` (one that ``starts_from_scene``) start from the empty scene they show."""
    started = time.perf_counter()
    limit = min(BACKGROUND_SCAN_FRAMES, math.ceil(BACKGROUND_SCAN_S * fps))
    scanned = itertools.islice(frames, limit)
    first = next(scanned, None)
    if first is None:
        return BackgroundScan(0, 0, None, time.perf_counter() - started)
    prepared = pipeline.prepare(first)  # Its size tells how many samples fit.
    fit = BACKGROUND_SCAN_BYTES // (2 * prepared.nbytes)
    sample: EvenSample[GrayImage] = EvenSample(max(LEAST_SAMPLES, min(BACKGROUND_SAMPLES, fit)))
    sample.offer(lambda: prepared)
    for frame in scanned:
        sample.offer(functools.partial(pipeline.prepare, frame))
    scene = estimate_scene_background(sample.items)
    if scene is not None:
        pipeline.start_from(scene)
    return BackgroundScan(sample.offered, len(sample.items), scene, time.perf_counter() - started)


class _Analysis:
    def __init__(
        self,
        source: VideoInput,
        out_dir: Path,
        options: AnalysisOptions,
        truth: Truth | None,
        progress: Progress | None,
        on_frame: FrameObserver | None,
    ) -> None:
        self.source = source
        self.on_frame = on_frame
        self.out = out_dir
        self.options = options
        self.progress = progress
        self.pipeline = Pipeline(options.pipeline, source.fps, options.calibration)
        self.annotator = Annotator()
        self.alarms = AlarmLogic(options.quiet_s)
        self.events: list[dict[str, Any]] = []
        self.tracks: dict[int, _TrackSummary] = {}
        self.frame_stats: list[dict[str, Any]] = []
        self.scoring = Scorer(truth, options.pipeline.min_area, source.size) if truth else None
        self.first_frame: Image | None = None
        self.key_frames: list[dict[str, Any]] = []
        self.background: dict[str, Any] | None = None

    def run(self) -> dict[str, Any]:
        started = time.perf_counter()
        if self.options.background_scan and self.pipeline.starts_from_scene:
            self.background = self._scan_background()
        tracks_csv = TracksCsv(self.out / "tracks.csv")
        video = AnnotatedVideo(
            self.out / "annotated.avi",
            self.source.fps,
            self.source.size,
            mp4=self.out / "annotated.mp4",
        )
        frames = 0
        try:
            for index, frame in self.source.indexed_frames(READ_AHEAD):
                if self.first_frame is None:
                    self.first_frame = frame
                # A skipped frame keeps its decode index: the frames after it keep their times.
                result = self.pipeline.process(frame, index=index)
                annotated = self.annotator(frame, result.detections, self.pipeline.tracker.trails())
                video.write(annotated, index)
                if self.on_frame is not None:
                    self.on_frame(annotated)
                tracks_csv.write(index, result.time_s, result.detections)
                self._record(result, annotated)
                frames += 1
                if self.progress:
                    self.progress(index + 1, self.source.expected_frames)
            video.pad_to(self.source.frames_read)
        finally:
            tracks_csv.close()
            video.close()
        if frames < MIN_FRAMES:  # A second frame that was there but did not decode.
            raise InputError(SINGLE_PICTURE.format(path=self.source.path))
        last = self.alarms.finish()
        if last is not None:
            self._close_event(last)
        elapsed = time.perf_counter() - started
        report = self._report(frames, elapsed)
        write_json(self.out / "events.json", {"events": self.events})
        write_json(self.out / "report.json", report)
        write_report_html(self.out / "report.html", report, self._html_extras())
        return report

    def _scan_background(self) -> dict[str, Any]:
        frames = self.source.frames(READ_AHEAD)
        try:
            return scan_background(self.pipeline, frames, self.source.fps).as_dict()
        finally:
            frames.close()

    def _record(self, result: FrameResult, annotated: Image) -> None:
        index, time_s = result.index, result.time_s
        if self.options.masks or self.scoring is not None:
            mask_full = to_size(result.mask, self.source.size)
            if self.options.masks:
                write_image(self.out / "masks" / f"{index:06d}.png", mask_full)
            if self.scoring is not None:
                self.scoring.add(index, [d.box for d in result.detections], mask_full)
        motion_area = sum(d.area for d in result.detections)
        stats = result.stats
        assert stats is not None  # The runner's pipeline measures every frame.
        self.frame_stats.append(
            {
                "frame": index,
                "time_s": round(time_s, 4),
                "grey_mean": round(stats.mean, 3),
                "grey_std": round(stats.std, 3),
                "objects": len(result.detections),
                "motion_area": round(motion_area, 1),
                "threshold": round(result.threshold, 2),
                "global_change": result.global_change,
            }
        )
        for d in result.detections:
            assert d.track_id is not None
            summary = self.tracks.get(d.track_id)
            if summary is None:
                summary = self.tracks[d.track_id] = _TrackSummary(
                    d.track_id, index, index, time_s, time_s
                )
            summary.add(index, time_s, d)
        update = self.alarms.update(index, time_s, result.detections)
        if update.started is not None:
            self._snapshot(update.started, annotated, result)
        if update.ended is not None:
            self._close_event(update.ended)

    def _snapshot(self, event: MotionEvent, annotated: Image, result: FrameResult) -> None:
        name = f"event-{event.id:04d}.jpg"
        write_image(self.out / "snapshots" / name, annotated)
        difference = difference_picture(result.difference, self.source.size)
        write_image(self.out / "differences" / name, difference)
        self.key_frames.append(
            {"event": event.id, "frame": result.index, "snapshot": f"snapshots/{name}"}
        )

    def _close_event(self, event: MotionEvent) -> None:
        record = event.as_dict()
        record["snapshot"] = f"snapshots/event-{event.id:04d}.jpg"
        record["difference"] = f"differences/event-{event.id:04d}.jpg"
        self.events.append(record)

    def _report(self, frames: int, elapsed: float) -> dict[str, Any]:
        config = self.options.pipeline
        timings = {
            stage: round(1000 * statistics.median(samples), 4)
            for stage, samples in self.pipeline.timings.items()
            if samples
        }
        report: dict[str, Any] = {
            "vigil_version": app.__version__,
            "input": self.options.input_name or str(self.source.path),
            "frames": frames,
            "frames_read": self.source.frames_read,
            "skipped_frames": self.source.skipped,
            "header_frames": self.source.header_frames,
            "ended_early": self.source.ended_early,
            "warnings": input_warnings(self.source, frames)
            + detection_warnings(config, self.source.size),
            "fps": self.source.fps,
            "size": list(self.source.size),
            "frame_numbers": self.source.frame_numbers,
            "duration_s": round(self.source.frames_read / self.source.fps, 4),
            "method": config.method,
            "settings": _settings(config, self.pipeline, self.options),
            "background_scan": self.background,
            "tracks": [t.as_dict() for t in sorted(self.tracks.values(), key=lambda t: t.track_id)],
            "events": len(self.events),
            "frame_stats": self.frame_stats,
            "timings": {
                "total_s": round(elapsed, 3),
                "frames_per_s": round(frames / elapsed, 2) if elapsed > 0 else None,
                "median_stage_ms": timings,
            },
        }
        if self.scoring is not None:
            report["evaluation"] = self.scoring.as_dict()
        return report

    def _html_extras(self) -> dict[str, Any]:
        return {
            "first_frame": self.first_frame,
            "paths": {tid: t.path for tid, t in self.tracks.items()},
            "speeds": {tid: (t.times, t.speeds) for tid, t in self.tracks.items()},
            "out_dir": self.out,
            "key_frames": self.key_frames,
        }


def input_warnings(source: VideoInput, frames: int) -> list[str]:
    """One line for each way the input was not read whole: frames skipped, an early end."""
    warnings = []
    skipped = source.skipped
    if skipped:
        shown = ", ".join(map(str, skipped[:MAX_FRAMES_NAMED]))
        more = f" ... ({len(skipped)} in all)" if len(skipped) > MAX_FRAMES_NAMED else ""
        warnings.append(
            f"{len(skipped)} {_frames(len(skipped))} did not decode and "
            f"{'were' if len(skipped) > 1 else 'was'} skipped: "
            f"{_frames(len(skipped))} {shown}{more} (0-based decode index)"
        )
    if source.ended_early:
        warnings.append(
            f"the video ended early: {frames} frames decoded of the {source.header_frames} "
            f"its header claims (cut short, or damaged from frame {source.frames_read} on)"
        )
    return warnings


SMALLEST_SIDE = 4.0
"""Pixels at detection size: an object of ``min_area`` narrower than this (as a square)
is all but wiped out by the morphology's 3x3 opening, and boxed to the nearest few
pixels of the input frame."""


def detection_warnings(config: PipelineConfig, size: tuple[int, int]) -> list[str]:
    """A line where objects of ``min_area`` are too small at the detection size to be
    found reliably, with the ``--detect-width`` that would keep them."""
    width = size[0]
    if config.min_area <= 0:
        return []
    scale = Downscale(config.detect_width).scale_for(width)
    side = math.sqrt(config.min_area) / scale
    if side >= SMALLEST_SIDE:
        return []
    wanted = math.ceil(width / scale * SMALLEST_SIDE / side / 32) * 32
    larger_area = f"a min area of {math.ceil(SMALLEST_SIDE**2 * scale**2)} px or more"
    # Wider than the frame: the min area is too small even at full size.
    remedy = f"a detection width of {wanted} (or {larger_area})" if wanted < width else larger_area
    return [
        f"objects of the min area ({config.min_area:g} px) are {side:.1f} px across at the "
        f"detection size ({round(width / scale)} of {width} px wide): they may be missed, "
        f"or boxed too large; {remedy} keeps them (--detect-width and --min-area, an "
        "upload's detect_width and min_area)"
    ]


def _frames(count: int) -> str:
    return "frame" if count == 1 else "frames"


def _settings(
    config: PipelineConfig, pipeline: Pipeline, options: AnalysisOptions
) -> dict[str, Any]:
    settings = asdict(config)
    settings["sensitivity_mode"] = "manual" if config.sensitivity is not None else "automatic"
    settings["threshold_in_force"] = round(pipeline.method.threshold, 2)
    settings["calibrated"] = options.calibration is not None
    settings["quiet_s"] = options.quiet_s
    # In force: a method that cannot start from a scene is not scanned for.
    settings["background_scan"] = options.background_scan and pipeline.starts_from_scene
    return settings
