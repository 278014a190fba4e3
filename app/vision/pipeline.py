"""The paper's pipeline as named stages, each swappable and timed.

frame -> grayscale -> histogram statistics -> downscale -> noise removal
      -> contrast enhancement -> segmentation (method + threshold)
      -> ignore zones -> morphology -> blobs (min area) -> tracking -> calibration
"""

from __future__ import annotations

import time
from collections import defaultdict, deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import ParamSpec, Protocol, TypeVar

import cv2
import numpy as np

from app.vision.blobs import BlobExtractor
from app.vision.calibration import GroundPlane, GroundTracker
from app.vision.detections import Detection
from app.vision.histogram import GreyStats, grey_stats
from app.vision.morphology import Morphology
from app.vision.motion import DEFAULT_METHOD, MotionResult, create_method
from app.vision.motion.adaptive import warm_up as warm_up_adaptive
from app.vision.preprocess import Denoise, DenoiseMethod, Downscale, Enhance, EnhanceMethod, to_gray
from app.vision.scene_background import SceneBackground
from app.vision.tracker import Tracker, TrackerConfig
from app.vision.types import GrayImage, Image, Mask
from app.vision.zones import IgnoreZones, Polygon

TIMING_SAMPLES = 5000
"""Per-stage timings kept (the most recent), enough for stable medians."""


@dataclass(frozen=True)
class PipelineConfig:
    method: str = DEFAULT_METHOD
    sensitivity: float | None = None
    """Grey-level threshold 1..255 (lower = more sensitive); None = automatic."""
    min_area: float = 100.0
    """Smallest object, in pixels of the input frame."""
    denoise: DenoiseMethod = "gaussian"
    denoise_kernel: int = 3
    enhance: EnhanceMethod = "none"
    detect_width: int = 320
    """Detection runs on frames at most this wide (0 = full size); boxes are mapped back."""
    open_kernel: int = 3
    close_kernel: int = 5
    ignore_zones: tuple[Polygon, ...] = ()
    """Polygons (fractions of the frame) where motion does not count."""
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    grey_stats: bool = True
    """Measure each frame's grey mean and deviation (the report's per-frame statistics).
    A live camera turns it off: its histogram viewers measure the frames they draw."""


MIN_DETECT_WIDTH = 32
"""Narrower than this, the detector's morphology and min area leave nothing to detect."""

MAX_DETECT_WIDTH = 7680
"""The widest detection that may be asked for: an 8K frame's (a frame is never enlarged,
so anything wider is its full size, and says so with 0)."""


def check_detect_width(width: int) -> int:
    """``width`` if it is a detection width (``PipelineConfig.detect_width``), else
    ValueError saying which are (its message names no field: the caller's does)."""
    if width != 0 and not MIN_DETECT_WIDTH <= width <= MAX_DETECT_WIDTH:
        raise ValueError(
            f"is 0 (full size) or {MIN_DETECT_WIDTH} to {MAX_DETECT_WIDTH} pixels, not {width}"
        )
    return width


WHOLE_VIEW_SHARE = 0.8
"""Motion over more than this share of the view (outside its ignore zones), from a method
that does not judge such changes itself (``judges_whole_view``), is the view changing at
once (a flash, a light switched, the method's first frames: OpenCV's KNN calls the whole
of its first frames motion), not objects: none are reported from it, and no track takes
its size."""


@dataclass(frozen=True, slots=True)
class FrameResult:
    index: int
    time_s: float
    detections: list[Detection]
    """Tracked objects (confirmed tracks) in input-frame pixels."""
    mask: Mask
    """Cleaned motion mask at detection resolution."""
    difference: GrayImage
    gray: GrayImage
    stats: GreyStats | None
    """None when the config's ``grey_stats`` is off."""
    threshold: float
    global_change: bool
    scale: float
    """Input pixels per detection pixel."""


class Pipeline:
    """Runs one video's frames, in order, through every stage."""

    def __init__(
        self,
        config: PipelineConfig | None = None,
        fps: float = 25.0,
        calibration: GroundPlane | None = None,
    ) -> None:
        self.config = config or PipelineConfig()
        self.fps = fps if fps > 0 else 25.0
        self.downscale = Downscale(self.config.detect_width)
        self.denoise = Denoise(self.config.denoise, self.config.denoise_kernel)
        self.enhance = Enhance(self.config.enhance)
        self.method = create_method(self.config.method, self.config.sensitivity, self.fps)
        self.zones = IgnoreZones(self.config.ignore_zones)
        self.morphology = Morphology(self.config.open_kernel, self.config.close_kernel)
        self.blobs = BlobExtractor(self.config.min_area)
        self.tracker = Tracker(self.config.tracker)
        self.ground = GroundTracker(calibration) if calibration else None
        self.timings: dict[str, deque[float]] = defaultdict(lambda: deque(maxlen=TIMING_SAMPLES))
        self._index = 0

    # Settings a live camera changes; each takes effect on the next frame.

    def set_sensitivity(self, sensitivity: float | None) -> None:
        self.method.sensitivity = sensitivity
        self.config = replace(self.config, sensitivity=sensitivity)

    def set_min_area(self, min_area: float) -> None:
        self.blobs = BlobExtractor(min_area)
        self.config = replace(self.config, min_area=min_area)

    def set_ignore_zones(self, polygons: tuple[Polygon, ...]) -> None:
        self.zones = IgnoreZones(polygons)
        self.config = replace(self.config, ignore_zones=polygons)

    def set_fps(self, fps: float) -> None:
        """The frame rate as measured (a live camera's): the method counts its times at it."""
        self.fps = fps
        self.method.set_fps(fps)

    def set_method(self, name: str) -> None:
        """Swap the segmentation method (it learns the scene afresh); tracks carry on."""
        self.method = create_method(name, self.method.sensitivity, self.fps)
        self.config = replace(self.config, method=name)

    def process(
        self,
        frame: Image,
        time_s: float | None = None,
        frame_size: tuple[int, int] | None = None,
        index: int | None = None,
    ) -> FrameResult:
        """One frame, in order. ``frame_size``: the original picture's (width, height)
        when ``frame`` is a reduced copy of it (decoded at reduced scale); boxes, areas
        and speeds then come back in the original's pixels. ``index``: the frame's decode
        index where frames before it did not decode (default: the one after the last);
        its time is then index / fps unless ``time_s`` says otherwise."""
        if index is not None:
            self._index = index
        index = self._index
        self._index += 1
        if time_s is None:
            time_s = index / self.fps
        clock = _StageClock(self.timings)
        gray = clock("grayscale", to_gray, frame)
        stats = clock("histogram", grey_stats, gray) if self.config.grey_stats else None
        small = self._prepare(gray, clock)
        frame_size = frame_size or (gray.shape[1], gray.shape[0])
        scale = frame_size[0] / small.shape[1]
        motion: MotionResult = clock("segment", self.method.apply, small)
        mask = clock("zones", self.zones, motion.mask)
        moving = cv2.countNonZero(mask)
        whole_view = not self.method.judges_whole_view and moving > WHOLE_VIEW_SHARE * (
            self.zones.watched(mask.shape[1], mask.shape[0])
        )
        if moving and not whole_view:
            mask = clock("morphology", self.morphology, mask)
            blobs = clock("blobs", self.blobs, mask, scale, frame_size)
        else:  # Most frames of a quiet scene: nothing to clean or measure.
            blobs = []
            clock.skipped("morphology", "blobs")
        detections = clock("track", self.tracker.update, blobs, time_s)
        if self.ground is not None:
            detections = clock("calibrate", self.ground.update, detections, time_s)
        return FrameResult(
            index,
            time_s,
            detections,
            mask,
            motion.difference,
            gray,
            stats,
            motion.threshold,
            motion.global_change or whole_view,
            scale,
        )

    def prepare(self, frame: Image) -> GrayImage:
        """``frame`` as segmentation sees it: grey, downscaled, denoised and enhanced."""
        return self._prepare(to_gray(frame), _untimed)

    @property
    def starts_from_scene(self) -> bool:
        """Whether the method can start from a scene estimated ahead (``start_from``)."""
        return self.method.starts_from_scene

    def start_from(self, scene: SceneBackground) -> None:
        """Have the method, one that ``starts_from_scene``, start from ``scene`` (estimated
        from frames as ``prepare`` gives them) rather than from the first frame."""
        self.method.seed(scene)

    def _prepare(self, gray: GrayImage, clock: Clock) -> GrayImage:
        small = clock("downscale", self.downscale, gray)
        small = clock("denoise", self.denoise, small)
        return clock("enhance", self.enhance, small)

    def reset(self) -> None:
        self.method.reset()
        self.tracker.reset()
        self._index = 0


def warm_up() -> None:
    """Compile the default pipeline's compiled stages (the first run on a machine) or load
    them from the cache now, rather than on a camera's first activated frame."""
    Pipeline().prepare(np.zeros((4, 4), np.uint8))
    warm_up_adaptive()


P = ParamSpec("P")
R = TypeVar("R")


class Clock(Protocol):
    def __call__(self, stage: str, fn: Callable[P, R], *args: P.args, **kwargs: P.kwargs) -> R: ...


def _untimed(stage: str, fn: Callable[P, R], *args: P.args, **kwargs: P.kwargs) -> R:
    """A ``Clock`` that keeps no time (work outside the frame-by-frame run)."""
    return fn(*args, **kwargs)


class _StageClock:
    """Times each stage call into a shared per-stage list (seconds)."""

    def __init__(self, timings: dict[str, deque[float]]) -> None:
        self.timings = timings

    def __call__(self, stage: str, fn: Callable[P, R], *args: P.args, **kwargs: P.kwargs) -> R:
        start = time.perf_counter()
        result = fn(*args, **kwargs)
        self.timings[stage].append(time.perf_counter() - start)
        return result

    def skipped(self, *stages: str) -> None:
        """Stages that had nothing to do this frame cost it nothing: every stage keeps
        one sample per frame, so a frame's stages can be added up."""
        for stage in stages:
            self.timings[stage].append(0.0)
