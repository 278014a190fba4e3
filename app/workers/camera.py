"""One thread per camera: read the source, run the engine between Activate and Stop, publish.

States a camera shows: ``connecting`` (first attempt), ``live``,
``reconnecting`` (a source that was live is lost and being retried, with the
reason), ``error`` (it never opened: the reason, retried with backoff), and
``stopped`` (the worker has ended).
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections import deque
from typing import Any, NamedTuple

import cv2

from app.core.config import Settings
from app.events.alarm import AlarmLogic, MotionEvent
from app.events.messages import Alarm, AlarmObject, CameraStatus, MotionEnd
from app.recording.activity import ActivityLog
from app.recording.recorder import Recorder
from app.sources.files import valid_fps
from app.sources.frames import FrameError, SourceFrame
from app.sources.live import (
    FrameSource,
    SourceError,
    open_source,
    parse_source,
    without_password,
)
from app.storage.db import Database
from app.storage.files import SnapshotStore
from app.vision.annotate import difference_picture
from app.vision.detections import Detection
from app.vision.pipeline import FrameResult, Pipeline, PipelineConfig
from app.vision.preprocess import Downscale
from app.vision.scene_background import estimate_recent_scene
from app.vision.types import GrayImage
from app.vision.zones import as_polygons
from app.workers.bus import Publisher
from app.workers.figures import TimeHistogram
from app.workers.hub import ANNOTATOR, EncodeCounter, FrameHub, LiveFrame, encode_jpeg

log = logging.getLogger("vigil.camera")

STABLE_FRAMES = 100
"""A worker that handled this many frames since its last restart was not failing in a row."""

DETECTION_WARMING = threading.Event()
"""Set while this process compiles the detection kernels, or loads them from the cache
(``CameraHost``'s warm-up): an activated camera waits for them, its picture going on
and its reason saying why, rather than stopping every frame in the first call."""

PREPARING = "preparing detection (on a first start it compiles, about 10 s)"

PLAIN_SLEEP_S = 0.25
"""Waits for the next frame up to this long (a camera of 4 fps or more) are a plain sleep,
about 40 us of CPU cheaper to wake from than an Event's wait (measured here: 60 against
105 us at 5 fps); a stop is then seen when it ends (this late at most), before another
frame."""

SETTING_FIELDS = ("sensitivity", "min_area", "method", "show_mask", "mask")

GLANCES = 9
"""Grey frames a camera keeps (one every ``scene_glance_s``) for the scene at
Activate: enough that someone who stood still for a few of them is not the scene."""
GLANCE_SIZE = Downscale(PipelineConfig.detect_width)

MEASURED_FRAMES = 16
"""Frames whose times give the camera's frame rate for detection (its times, such as how
long a stopped person is kept, are counted in frames)."""

FPS_SLACK = 0.15
"""A measured frame rate this far (as a share) from detection's is taken by detection."""

CLIPS_WAIT_S = 3.0
"""How long a stopping worker waits for its clips to be written (else the next start
finishes them)."""


class EventRow(NamedTuple):
    """An open event's row in the database: its id, and its ``started_at`` (wall time)."""

    id: int
    started_at: float


class CameraWorker:
    def __init__(
        self,
        camera: dict[str, Any],
        settings: Settings,
        db: Database,
        snapshots: SnapshotStore,
        bus: Publisher,
    ) -> None:
        self.camera_id: int = camera["id"]
        self.name: str = camera["name"]
        self.source_text: str = camera["source"]
        self.settings = settings
        self.db = db
        self.snapshots = snapshots
        self.bus = bus
        self.hub = FrameHub()
        self.encodes = EncodeCounter()
        self._config: dict[str, Any] = {k: camera[k] for k in SETTING_FIELDS}
        self._want_active: bool = bool(camera.get("active"))
        self._pending: dict[str, Any] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(
            target=self._run, name=f"camera-{self.camera_id}", daemon=True
        )
        self.state = "connecting"
        self.reason = ""
        self.fps = 0.0
        self.source_fps: float | None = None
        self.frames = 0
        self.processed = 0
        self.objects = 0
        self.motion = 0.0
        self.threshold: float | None = None
        self.last_alarm: float | None = None
        self.alarms = 0
        self.detect_times = TimeHistogram()
        self._times: deque[float] = deque(maxlen=64)
        self._measured_fps = 0.0
        """The frame rate last measured over ``MEASURED_FRAMES`` or more, reconnects aside."""
        self._pipeline: Pipeline | None = None
        self._alarms: AlarmLogic | None = None
        self._event_rows: dict[int, EventRow] = {}
        """The open events' rows, by the alarm logic's event id."""
        self._activated_at = 0.0
        self._last_status = 0.0
        self._source: FrameSource | None = None
        self._was_live = False
        self._failures = 0
        self._glances: deque[GrayImage] = deque(maxlen=GLANCES)
        self._next_glance = 0.0
        self.recorder = Recorder(self.camera_id, settings, db)
        self._activity = ActivityLog(self.camera_id, db)
        self._storage_error: str | None = None
        """The storage error last published (snapshots' or clips')."""

    # Control, from any thread -------------------------------------------------------------

    def start(self) -> None:
        self._thread.start()

    def request_stop(self) -> None:
        self._stop.set()
        self.hub.close()

    def join(self, timeout: float) -> bool:
        self._thread.join(timeout)
        return not self._thread.is_alive()

    @property
    def active(self) -> bool:
        return self._want_active

    def set_active(self, active: bool) -> None:
        with self._lock:
            self._want_active = active
        self._publish_status()

    def update(self, **changes: Any) -> None:
        """New settings; the worker applies them before its next frame."""
        if "name" in changes:
            self.name = changes["name"]
        with self._lock:
            self._pending.update({k: v for k, v in changes.items() if k in SETTING_FIELDS})

    def status(self) -> dict[str, Any]:
        return status_fields(
            self.camera_id,
            state=self.state,
            reason=self.reason,
            fps=self.fps,
            source_fps=self.source_fps,
            active=self._want_active,
            frames=self.frames,
            viewers=self.hub.viewers,
            processed=self.processed,
            objects=self.objects,
            motion=self.motion,
            threshold=self.threshold,
            last_alarm=self.last_alarm,
            alarms=self.alarms,
            detect_seconds=self.detect_times.wire(),
        )

    # The thread ---------------------------------------------------------------------------

    def _run(self) -> None:
        backoff = self.settings.reconnect_min_s
        try:
            while not self._stop.is_set():
                frames_before = self.frames
                try:
                    backoff = self._connect_and_stream(backoff)
                except Exception as exc:
                    self._worker_failed(exc, self.frames - frames_before)
        finally:
            with contextlib.suppress(Exception):  # Ending the open event is best effort here.
                self._deactivate()
            self.recorder.wait(CLIPS_WAIT_S)
            self._set_state("stopped", "")

    def _connect_and_stream(self, backoff: float) -> float:
        """Open the source and stream until it is lost; the backoff for the next attempt.

        Source failures are the camera's: shown, retried with backoff. Any other
        exception is a fault of the worker itself and reaches ``_worker_failed``.
        """
        longer = min(backoff * 2, self.settings.reconnect_max_s)
        try:
            spec = parse_source(self.source_text)
            source = open_source(spec, self.settings.open_timeout_ms, self.settings.read_timeout_ms)
        except (SourceError, ValueError) as exc:
            self._failed(str(exc), backoff)
            return longer
        except (cv2.error, OSError) as exc:
            log.exception(
                "camera %s: cannot open %s", self.camera_id, without_password(self.source_text)
            )
            self._failed(f"cannot open source: {exc}", backoff)
            return longer
        self._source = source
        try:
            self._stream(source)
        except SourceError as exc:
            # An open event ends with the picture; detection starts afresh on return.
            self._deactivate()
            if self.state != "live":  # Nothing came that decodes: it did not really open.
                self._failed(str(exc), backoff)
                return longer
            self._lost(str(exc), self.settings.reconnect_min_s)
        finally:
            self._source = None
            source.close()
        return self.settings.reconnect_min_s

    def _worker_failed(self, exc: Exception, frames_handled: int) -> None:
        """A fault of the worker (a bug, the database): restart; if it keeps failing, say so.

        Failures in a row (each within ``STABLE_FRAMES`` of the last restart) up to
        ``worker_failures_limit`` show ``reconnecting``; from then on the camera shows
        ``error`` with the last reason, and is retried at the longest backoff.
        """
        log.exception("camera %s: worker failed", self.camera_id)
        self._failures = self._failures + 1 if frames_handled < STABLE_FRAMES else 1
        with contextlib.suppress(Exception):  # The fault may be the database itself.
            self._deactivate()
        if self._failures >= self.settings.worker_failures_limit:
            wait_s = self.settings.reconnect_max_s
            reason = f"worker failed {self._failures} times in a row: {exc}"
            self._set_state("error", f"{reason}; retrying every {wait_s:g} s")
        else:
            wait_s = self.settings.reconnect_min_s * 2**self._failures
            self._set_state("reconnecting", f"worker error: {exc}; restarting")
        self._stop.wait(wait_s)

    def _failed(self, reason: str, wait_s: float) -> None:
        state = "reconnecting" if self._was_live else "error"
        self._set_state(state, f"{reason}; retrying in {wait_s:.1f} s")
        self._stop.wait(wait_s)

    def _lost(self, reason: str, wait_s: float) -> None:
        self._set_state("reconnecting", reason)
        self._stop.wait(wait_s)

    def _stream(self, source: FrameSource) -> None:
        self._glances.clear()  # A source opened anew may show another view.
        self.source_fps = round(source.fps, 3)
        period = 1.0 / source.fps if source.paced and source.fps > 0 else 0.0
        due = time.monotonic()
        first = True
        bad_frames = 0
        while not self._stop.is_set():
            if period:
                delay = due - time.monotonic()
                if 0 < delay <= PLAIN_SLEEP_S:
                    time.sleep(delay)
                    if self._stop.is_set():
                        return
                elif delay > 0 and self._stop.wait(delay):
                    return
                due = max(due + period, time.monotonic() - 1.0)  # Catch up at most a second.
            try:
                frame = source.read()
                if first:
                    # Live once a picture decodes: a camera sending only broken JPEGs is
                    # not live, though an idle one decodes nothing (detection's grey, kept).
                    frame.gray(PipelineConfig.detect_width)
                    self._was_live = True
                    self._set_state("live", "")
                    first = False
                self._handle(frame)
            except FrameError as exc:
                # One bad frame is skipped; a camera that sends nothing else is lost.
                bad_frames += 1
                if bad_frames >= self.settings.bad_frames_limit:
                    raise SourceError(f"{exc} ({bad_frames} frames in a row)") from exc
                continue
            bad_frames = 0

    def _handle(self, frame: SourceFrame) -> None:
        now_mono = time.monotonic()
        now = time.time()
        self._apply_pending(frame, now_mono)
        self.frames += 1
        self._times.append(now_mono)
        if len(self._times) >= 2 and self._times[-1] > self._times[0]:
            self.fps = (len(self._times) - 1) / (self._times[-1] - self._times[0])
            # A rate no source may claim is a burst (frames buffered over a reconnect).
            if len(self._times) >= MEASURED_FRAMES and valid_fps(self.fps):
                self._measured_fps = self.fps
                pipeline = self._pipeline
                if pipeline is not None and abs(self.fps - pipeline.fps) > FPS_SLACK * pipeline.fps:
                    pipeline.set_fps(self.fps)  # Built before the rate was measured.
        live = LiveFrame(
            self.frames, now, frame, quality=self.settings.jpeg_quality, counter=self.encodes
        )
        pipeline, alarms = self._pipeline, self._alarms
        if pipeline is not None and alarms is not None:
            # Detection needs grey at its own width only: a JPEG decodes to that directly.
            gray = frame.gray(pipeline.config.detect_width)
            started = time.perf_counter()
            result = pipeline.process(gray, now_mono - self._activated_at, frame.size)
            self.detect_times.observe(time.perf_counter() - started)
            self.processed += 1
            live.detections = result.detections
            live.trails = pipeline.tracker.trails()
            live.gray, live.stats = result.gray, result.stats
            if self._config.get("show_mask"):
                live.mask = result.mask
            self.objects = len(result.detections)
            self.threshold = result.threshold
            self.motion = float(sum(d.area for d in result.detections)) / (
                frame.size[0] * frame.size[1]
            )
            update = alarms.update(result.index, result.time_s, result.detections)
            if update.started is not None:
                self._alarm(update.started, live, result, now)
                self._record_start(update.started, now_mono, now)
            elif update.newcomers and alarms.current is not None:
                self._alarm(alarms.current, live, result, now)
            if update.ended is not None:
                self._motion_end(update.ended)
            self._record(frame, bool(result.detections), now_mono, now)
        if now_mono >= self._next_glance:
            # While detecting too, so that a Stop and a quick Activate again start from
            # the scene.
            glance = _glance(frame)
            if self._glances and self._glances[-1].shape != glance.shape:
                self._glances.clear()  # The picture's size changed: another view.
            self._glances.append(glance)
            self._next_glance = now_mono + self.settings.scene_glance_s
        self.hub.publish(live)
        if now_mono - self._last_status >= self.settings.status_interval_s:
            self._publish_status()

    def _apply_pending(self, frame: SourceFrame, now_mono: float) -> None:
        with self._lock:
            pending, self._pending = self._pending, {}
            want_active = self._want_active
        old = self._config
        if pending:  # Rarely: no copy on the frames without.
            self._config = {**old, **pending}
        waiting = want_active and self._pipeline is None and DETECTION_WARMING.is_set()
        if waiting != (self.reason == PREPARING):
            self._set_state("live", PREPARING if waiting else "")
        if waiting:
            return
        if want_active and self._pipeline is None:
            self._pipeline = self._new_pipeline(self._frame_rate())
            self._start_from_glances(self._pipeline, frame)
            self._alarms = AlarmLogic(self.settings.quiet_s, self.settings.alarm_gap_s)
            self._activated_at = now_mono  # The first frame detected is at 0 s.
        elif not want_active and self._pipeline is not None:
            self._deactivate()
        pipeline = self._pipeline
        if pipeline is None or not pending:
            return
        if self._config["method"] != old["method"]:
            try:
                pipeline.set_method(self._config["method"])
            except ValueError:
                log.exception("camera %s: keeping method %s", self.camera_id, old["method"])
                self._config = old
                return
        if self._config["sensitivity"] != old["sensitivity"]:
            pipeline.set_sensitivity(self._config["sensitivity"])
        if self._config["min_area"] != old["min_area"]:
            pipeline.set_min_area(float(self._config["min_area"]))
        if self._config["mask"] != old["mask"]:
            pipeline.set_ignore_zones(as_polygons(self._config["mask"]))

    def _frame_rate(self) -> float:
        """Frames a second, as last measured over ``MEASURED_FRAMES`` (an MJPEG stream's
        header says 25 whatever the camera sends; a reconnect starts the count again),
        else as the source says."""
        if self._measured_fps > 0:
            return self._measured_fps
        return float(getattr(self._source, "fps", 25.0))

    def _new_pipeline(self, fps: float) -> Pipeline:
        config = PipelineConfig(
            method=self._config["method"],
            sensitivity=self._config["sensitivity"],
            min_area=float(self._config["min_area"]),
            ignore_zones=as_polygons(self._config["mask"]),
            grey_stats=False,
        )
        return Pipeline(config, fps)

    def _start_from_glances(self, pipeline: Pipeline, frame: SourceFrame) -> None:
        """The scene as the last glances and ``frame`` (the newest) show it, for
        detection to start from: someone walking when Activate is pressed is motion, not
        background that leaves a ghost; a lamp that came on a moment ago is scene."""
        if not pipeline.starts_from_scene:
            return
        now = _glance(frame)
        glances = [
            pipeline.prepare(glance) for glance in self._glances if glance.shape == now.shape
        ]
        scene = estimate_recent_scene(glances, pipeline.prepare(now))
        if scene is not None:
            pipeline.start_from(scene)

    def _deactivate(self) -> None:
        alarms = self._alarms
        self._pipeline = None  # First: detection stops even if ending the event fails.
        self._alarms = None
        self.objects = 0
        self.motion = 0.0
        self.threshold = None
        self._stop_recording()  # Before the event's end: its clip ends now, as it does.
        if alarms is not None:
            ended = alarms.finish()
            if ended is not None:
                self._motion_end(ended)

    # Alarms -------------------------------------------------------------------------------

    def _alarm(self, event: MotionEvent, live: LiveFrame, result: FrameResult, now: float) -> None:
        """A new event, or a new object within the open one: snapshots and an ``alarm``.

        The event row is committed before the alarm goes out, so every event a client
        hears of is in the database. A snapshot the disk refuses (full, read-only)
        costs only the pictures: the event stands and the alarm goes out without them;
        a ``status`` message with ``storage_error`` marks the start and the end of
        such a spell, once each.
        """
        detections: list[Detection] = list(result.detections)
        boxes = [d.box.as_list() for d in detections]
        picture = ANNOTATOR(live.source.image(), detections, live.trails)
        difference = difference_picture(result.difference, live.source.size)
        row = self._event_rows.get(event.id)
        if row is None:
            track_ids = sorted(d.track_id for d in detections if d.track_id is not None)
            row_id = self.db.add_event(self.camera_id, now, boxes, event.max_area, track_ids)
            row = self._event_rows[event.id] = EventRow(row_id, now)
        event_id = row.id
        saved: list[tuple[str, str, int]] = []
        for kind, image in (("frame", picture), ("difference", difference)):
            data = encode_jpeg(image, 90)
            try:
                relative = self.snapshots.save(self.camera_id, now, kind, data, event_id)
            except OSError:
                break  # The store keeps the reason; the second picture would fail alike.
            saved.append((kind, relative, len(data)))
        # Both rows in one commit (each commit waits for the disk), after both files.
        added = self.db.add_snapshots(self.camera_id, event_id, now, saved) if saved else []
        ids = {kind: snapshot_id for (kind, _, _), snapshot_id in zip(saved, added, strict=True)}
        failing = self.snapshots.failure(self.camera_id)
        if failing != self._storage_error:
            if failing:
                log.warning(
                    "camera %s: snapshots not saved under %s: %s",
                    self.camera_id,
                    self.snapshots.root,
                    failing,
                )
            else:
                log.info("camera %s: snapshots saved again", self.camera_id)
        self._report_storage()
        self.last_alarm = now
        self.alarms += 1
        urls = {kind: f"/api/snapshots/{snapshot_id}.jpg" for kind, snapshot_id in ids.items()}
        self.bus.publish(
            Alarm(
                camera_id=self.camera_id,
                camera_name=self.name,
                event_id=event_id,
                ts=now,
                frame=result.index,
                boxes=boxes,
                objects=[_alarm_object(d) for d in detections],
                snapshot=urls.get("frame"),
                snapshot_id=ids.get("frame"),
                difference=urls.get("difference"),
                node=self.settings.node,
            )
        )

    def _motion_end(self, event: MotionEvent) -> None:
        """The event is over: its row ends, and ``motion_end`` says so, with the same end.

        An event lasts from its first frame with motion to its last, as ``vigil analyze``'s
        events do: the quiet seconds that tell it is over (``quiet_s``), or a Stop before
        them, are not part of it. So ``ended_at`` is the time of its last moving frame, on
        the clock of ``started_at`` (the time of its first), and the message's ``ts`` and
        ``duration_s`` are ``ended_at`` and ``ended_at - started_at``, as ``/api/events``
        and the page show them.
        """
        row = self._event_rows.pop(event.id, None)
        if row is None:
            return
        ended_at = row.started_at + max(0.0, event.end_time_s - event.start_time_s)
        self.db.end_event(row.id, ended_at, event.max_area, sorted(event.track_ids))
        clip, clip_s = self.recorder.end(row.id, time.monotonic())
        self.bus.publish(
            motion_end_message(
                self.camera_id,
                row.id,
                ended_at,
                ended_at - row.started_at,
                event.max_area,
                clip,
                clip_s,
                node=self.settings.node,
            )
        )

    # Recordings (app/recording/) ------------------------------------------------------------

    def _record_start(self, event: MotionEvent, now_mono: float, now: float) -> None:
        """A new event: its clip starts, from the pre-roll before this frame."""
        row = self._event_rows.get(event.id)
        if row is not None:
            self.recorder.start(row.id, now_mono, now, self._frame_rate())
            self._report_storage()

    def _record(self, frame: SourceFrame, moving: bool, now_mono: float, now: float) -> None:
        """Every frame detection saw: to the pre-roll and the clips being recorded, and its
        moving share to the activity history."""
        self.recorder.feed(frame, moving, now_mono, now)
        self._activity.note(now, self.motion, now_mono)
        self._report_storage()

    def _stop_recording(self) -> None:
        self.recorder.stop()
        self._activity.flush(finished=True)

    def _report_storage(self) -> None:
        """A ``status`` with ``storage_error`` when saving snapshots or clips starts or stops
        failing (once each)."""
        failing = self.snapshots.failure(self.camera_id) or self.recorder.failure()
        if failing != self._storage_error:
            self._storage_error = failing
            self.bus.publish(CameraStatus(**self.status(), storage_error=failing))

    # Status -------------------------------------------------------------------------------

    def _set_state(self, state: str, reason: str) -> None:
        changed = (state, reason) != (self.state, self.reason)
        self.state, self.reason = state, reason
        if state != "live":
            self.fps = 0.0
            self._times.clear()
        if changed:
            if state in ("error", "reconnecting"):
                log.warning("camera %s %s: %s", self.camera_id, state, reason)
            self._publish_status()

    def _publish_status(self) -> None:
        self._last_status = time.monotonic()
        self.bus.publish(CameraStatus(**self.status()))


def status_fields(
    camera_id: int,
    *,
    state: str = "connecting",
    reason: str = "",
    fps: float = 0.0,
    source_fps: float | None = None,
    active: bool = False,
    frames: int = 0,
    viewers: int = 0,
    processed: int = 0,
    objects: int = 0,
    motion: float = 0.0,
    threshold: float | None = None,
    last_alarm: float | None = None,
    alarms: int = 0,
    detect_seconds: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """A camera's status as the API and ``status`` messages show it; the defaults are a
    new camera's, before its first frame."""
    return {
        "camera_id": camera_id,
        "state": state,
        "reason": reason,
        "fps": round(fps, 2),
        "source_fps": source_fps,
        "active": active,
        "frames": frames,
        "viewers": viewers,
        "processed": processed,
        "objects": objects,
        "motion": round(motion, 5),
        "threshold": None if threshold is None else round(threshold, 1),
        "last_alarm": last_alarm,
        "alarms": alarms,
        "detect_seconds": detect_seconds or TimeHistogram().wire(),
    }


STATUS_FIELDS = tuple(status_fields(0))
"""The fields of a ``status`` message, and of the API's camera besides its settings."""


def motion_end_message(
    camera_id: int,
    event_id: int,
    ts: float,
    duration_s: float,
    max_area: float,
    clip: str | None = None,
    clip_s: float | None = None,
    node: str | None = None,
) -> MotionEnd:
    """The ``motion_end`` message on /ws: an event of a camera ended at ``ts``; its clip's
    URL and length, if it has one; ``node``: the node that ended it."""
    message = MotionEnd(
        camera_id=camera_id,
        event_id=event_id,
        ts=ts,
        duration_s=round(duration_s, 3),
        max_area=round(max_area, 1),
        clip=clip,
        clip_s=None if clip_s is None else round(clip_s, 3),
    )
    # Unset, it is left out of the wire form.
    return message if node is None else message.model_copy(update={"node": node})


def _alarm_object(d: Detection) -> AlarmObject:
    return AlarmObject(
        track_id=d.track_id,
        box=d.box.as_list(),
        area=round(d.area, 1),
        speed_px_s=round(d.speed_px_s, 2),
        distance_px=round(d.distance_px, 2),
    )


def _glance(frame: SourceFrame) -> GrayImage:
    """A grey frame to keep for the scene at Activate. At detection size: a decoded 4K
    frame, kept nine times, would hold 75 MB (and a JPEG's grey is detection's, decoded
    already)."""
    return GLANCE_SIZE(frame.gray(PipelineConfig.detect_width))
