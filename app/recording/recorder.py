"""A camera's clips: the pre-roll it keeps while activated, and a recording per event.

The camera's worker thread feeds ``Recorder`` every frame it detects on, and tells it
when an event starts and ends. While nothing moves that costs next to nothing: a JPEG
camera's frame is kept by reference (its own bytes), a decoded one converted to I420;
nothing is decoded or encoded. An event starts a ``Recording``: its own thread, which
takes the pre-roll from ``VIGIL_PRE_ROLL_S`` before the first moving frame, then every
frame up to ``VIGIL_POST_ROLL_S`` after the last, and encodes them into the event's clip
(``app.recording.mp4``) as they come.

The worker never waits for a recording. Frames wait in the recording's queue, up to
twice ``VIGIL_PRE_ROLL_MB``; past that (a disk or a CPU too slow for the encoder) the
clip loses frames, detection none, and the clip's ``clip_error`` counts them. A disk that
refuses the clip (full, read-only) costs the clip only: the event stands, the clip keeps
what was written, and the camera's ``storage_error`` says why.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections import deque

import av

from app.core.config import Settings
from app.recording.mp4 import ClipFrame, EncoderSettings, H264Writer, decoded_clip_frame
from app.recording.preroll import PreRoll
from app.sources.frames import SourceFrame
from app.storage.clips import ClipStore, clip_length_s, repair
from app.storage.db import Database

log = logging.getLogger("vigil.recording")

MB = 1024 * 1024


def clip_url(event_id: int) -> str:
    return f"/api/events/{event_id}/clip.mp4"


def clip_frame(frame: SourceFrame, mono: float, wall: float) -> ClipFrame:
    """A frame as a clip keeps it: a JPEG camera's own bytes, else I420 pixels."""
    if frame.jpeg is not None:
        return ClipFrame(mono, wall, frame.size, jpeg=frame.jpeg)
    return decoded_clip_frame(frame.image(), mono, wall)


class Recording:
    """One event's clip, encoded in its own thread from the frames ``offer`` gives it."""

    def __init__(
        self,
        event_id: int,
        camera_id: int,
        relative: str,
        store: ClipStore,
        db: Database,
        first: list[ClipFrame],
        fps: float,
        post_roll_s: float,
        max_backlog: int,
        encoder: EncoderSettings,
        moving_at: float,
    ) -> None:
        self.event_id = event_id
        self.camera_id = camera_id
        self.relative = relative
        self.store = store
        self.db = db
        self.fps = fps
        self.post_roll_s = post_roll_s
        self.max_backlog = max_backlog
        self.encoder = encoder
        self.first_mono = first[0].mono if first else moving_at
        self.last_moving = moving_at
        self.last_taken = self.first_mono
        self.ended = False
        """The event is over: no frame after its post-roll is taken."""
        self._past_post_roll = False
        """A frame past the post-roll came: the clip has every frame it may take so far."""
        self.failed: str | None = None
        self.dropped = 0
        self.length_s: float | None = None
        """The clip's length once written."""
        self._queue: deque[ClipFrame] = deque()
        self._backlog = 0
        self._held: list[ClipFrame] = []
        """Frames past the post-roll while the event may yet go on (its quiet seconds)."""
        self._closing = False
        self._wake = threading.Condition()
        self.done = threading.Event()
        for frame in first:
            self._put(frame, always=True)
        self._thread = threading.Thread(
            target=self._run, name=f"clip-{camera_id}-{event_id}", daemon=True
        )
        self._thread.start()

    # The worker's side ----------------------------------------------------------------------

    def offer(self, frame: ClipFrame, moving: bool) -> bool:
        """The camera's next frame; False once the clip takes no more (then it finishes)."""
        if self._closing:
            return False
        # Once the event is over, motion is the next event's (in its own clip): this one
        # still ends at its post-roll, or back-to-back events would keep it open for ever.
        if moving and not self.ended:
            self.last_moving = frame.mono
            for held in self._held:  # The event went on: its quiet frames are in the clip.
                self._put(held)
            self._held.clear()
            self._past_post_roll = False
        if frame.mono <= self.last_moving + self.post_roll_s:
            self._put(frame)
            return True
        if self.ended:
            self.finish()
            return False
        self._held.append(frame)
        self._past_post_roll = True
        return True

    def end(self, now: float) -> None:
        """The event is over (seen at ``now``, the monotonic time of the frame about to be
        offered): the clip ends ``post_roll_s`` after its last moving frame."""
        self.ended = True
        self._held.clear()
        if now > self.last_moving + self.post_roll_s:
            self._past_post_roll = True  # This frame is past it: the clip has all it takes.

    def finish(self) -> None:
        """Take no more frames: encode those queued, and close the clip."""
        self._held.clear()
        with self._wake:
            self._closing = True
            self._wake.notify()

    def planned_s(self) -> float:
        """The clip's length as far as known: what it took, and the rest of its post-roll
        unless it has finished."""
        if self.length_s is not None:
            return self.length_s
        end = self.last_taken
        if not (self._closing or self._past_post_roll):
            end = max(end, self.last_moving + self.post_roll_s)
        return end - self.first_mono + 1.0 / self.fps

    def join(self, timeout: float) -> bool:
        return self.done.wait(timeout)

    def _put(self, frame: ClipFrame, always: bool = False) -> None:
        with self._wake:
            if not always and self._backlog + frame.nbytes > self.max_backlog:
                self.dropped += 1
                return
            self._queue.append(frame)
            self._backlog += frame.nbytes
            self.last_taken = max(self.last_taken, frame.mono)
            self._wake.notify()

    # The recording's thread ----------------------------------------------------------------

    def _next(self) -> ClipFrame | None:
        with self._wake:
            self._wake.wait_for(lambda: self._queue or self._closing)
            if not self._queue:
                return None
            frame = self._queue.popleft()
            self._backlog -= frame.nbytes
            return frame

    def _run(self) -> None:
        writer: H264Writer | None = None
        try:
            path = self.store.path(self.relative)
            with path.open("wb", buffering=0) as file:
                writer = H264Writer(file, self.fps, self.encoder)
                while (frame := self._next()) is not None:
                    try:
                        writer.write(frame, frame.mono)
                    except (ValueError, av.InvalidDataError):
                        self.dropped += 1  # A JPEG the camera sent damaged: the next may do.
                writer.close(durable=True)
            self._written(path.stat().st_size, writer.length_s)
        except OSError as exc:
            if writer is not None:
                writer.abandon()
            self._refused(self.store.failed(self.camera_id, exc))
        except Exception as exc:
            log.exception("camera %s: clip of event %s failed", self.camera_id, self.event_id)
            if writer is not None:
                writer.abandon()
            self._refused(f"the encoder failed: {exc}")
        finally:
            with self._wake:  # Whatever is left goes: nobody will encode it.
                self._closing = True
                self._queue.clear()
                self._backlog = 0
            self.done.set()

    def _written(self, size: int, length_s: float) -> None:
        self.length_s = round(length_s, 3)
        error = None
        if self.dropped:
            error = f"{self.dropped} frames left out (the encoder or the disk was too slow)"
            log.warning("camera %s: clip of event %s: %s", self.camera_id, self.event_id, error)
        self.store.written(self.camera_id)
        if not self.db.finish_clip(self.event_id, size, self.length_s, error):
            self.store.delete(self.relative)  # The event was deleted meanwhile.

    def _refused(self, reason: str) -> None:
        """The disk refused the clip, or the encoder failed: keep what plays, say why."""
        self.failed = reason
        log.warning(
            "camera %s: clip of event %s not saved whole under %s: %s",
            self.camera_id,
            self.event_id,
            self.store.root,
            reason,
        )
        with contextlib.suppress(ValueError):
            path = self.store.path(self.relative)
            size = repair(path)
            length = clip_length_s(path) if size else 0.0
            if size and length > 0:
                self.length_s = round(length, 3)
                if self.db.finish_clip(self.event_id, size, self.length_s, f"{reason}: cut short"):
                    return
        self.store.delete(self.relative)
        self.db.drop_clip(self.event_id, reason)


class Recorder:
    """A camera's pre-roll and recordings, fed by its worker thread (and only by it)."""

    def __init__(self, camera_id: int, settings: Settings, db: Database) -> None:
        self.camera_id = camera_id
        self.enabled = settings.clips
        self.pre_roll_s = settings.pre_roll_s
        self.post_roll_s = settings.post_roll_s
        self.db = db
        self.store = ClipStore(settings.clips_dir)
        max_bytes = int(settings.pre_roll_mb * MB)
        self.max_backlog = 2 * max_bytes
        self.encoder = EncoderSettings(settings.clip_preset, settings.clip_crf)
        self.preroll = PreRoll(settings.pre_roll_s, max_bytes)
        self._recording: dict[int, Recording] = {}
        """By event id: the recordings still taking frames."""
        self._finishing: list[Recording] = []

    def failure(self) -> str | None:
        """Why the camera's last clip could not be written; None once one is."""
        return self.store.failure(self.camera_id)

    def feed(self, frame: SourceFrame, moving: bool, mono: float, wall: float) -> None:
        """A frame detection has seen (``moving``: with motion in it)."""
        if not self.enabled:
            return
        item = clip_frame(frame, mono, wall)
        for event_id, recording in list(self._recording.items()):
            if not recording.offer(item, moving):
                self._retire(event_id)
        self.preroll.add(item)

    def start(self, event_id: int, mono: float, wall: float, fps: float) -> None:
        """Event ``event_id`` starts with the frame about to be fed: record its clip."""
        if not self.enabled or event_id in self._recording:
            return
        first = self.preroll.since(mono - self.pre_roll_s) if self.pre_roll_s > 0 else []
        try:
            relative, _ = self.store.create(self.camera_id, wall, event_id)
        except OSError:
            self.db.drop_clip(event_id, self.failure() or "cannot write")
            return
        self.db.start_clip(event_id, relative, first[0].wall if first else wall)
        self._recording[event_id] = Recording(
            event_id,
            self.camera_id,
            relative,
            self.store,
            self.db,
            first,
            fps,
            self.post_roll_s,
            self.max_backlog,
            self.encoder,
            mono,
        )

    def end(self, event_id: int, now: float) -> tuple[str | None, float | None]:
        """Event ``event_id`` is over, as the frame at ``now`` (monotonic) tells, before it is
        fed: its clip's URL and length (None, None: it has none)."""
        recording = self._recording.get(event_id) or next(
            (r for r in self._finishing if r.event_id == event_id), None
        )
        if recording is None:
            return None, None
        recording.end(now)
        if recording.failed is not None and recording.length_s is None:
            return None, None
        return clip_url(event_id), round(recording.planned_s(), 3)

    def stop(self) -> None:
        """Detection stops: every clip ends with the frames it has; the pre-roll goes."""
        for event_id, recording in list(self._recording.items()):
            recording.finish()
            self._retire(event_id)
        self.preroll.clear()

    def wait(self, timeout: float) -> bool:
        """Until every clip is written, at most ``timeout`` seconds; True when they are."""
        deadline = time.monotonic() + timeout
        for recording in list(self._finishing):
            if not recording.join(max(0.0, deadline - time.monotonic())):
                return False
        self._finishing = [r for r in self._finishing if not r.done.is_set()]
        return True

    def _retire(self, event_id: int) -> None:
        recording = self._recording.pop(event_id)
        self._finishing = [r for r in self._finishing if not r.done.is_set()]
        self._finishing.append(recording)
