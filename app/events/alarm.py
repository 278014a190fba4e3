"""Alarm logic: when motion starts an event and when quiet ends it.

The same rules serve the live cameras and offline analysis: an event starts
on the first frame with a confirmed moving object, stays open while motion
continues, and ends once the scene has been quiet for ``quiet_s`` seconds.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from app.vision.detections import Detection


@dataclass
class MotionEvent:
    id: int
    start_frame: int
    start_time_s: float
    end_frame: int
    end_time_s: float
    max_area: float = 0.0
    peak_frame: int = 0
    track_ids: set[int] = field(default_factory=set)
    announced: set[int] = field(default_factory=set)
    """Tracks an alarm of this event has named."""
    last_alarm_s: float = 0.0

    def as_dict(self) -> dict[str, object]:
        return {
            "id": self.id,
            "start_frame": self.start_frame,
            "end_frame": self.end_frame,
            "start_time_s": round(self.start_time_s, 4),
            "end_time_s": round(self.end_time_s, 4),
            "max_area": round(self.max_area, 1),
            "peak_frame": self.peak_frame,
            "track_ids": sorted(self.track_ids),
        }


@dataclass(frozen=True, slots=True)
class AlarmUpdate:
    started: MotionEvent | None = None
    ended: MotionEvent | None = None
    newcomers: tuple[int, ...] = ()
    """Tracks that joined the event already open: each new movement is worth an alarm."""


class AlarmLogic:
    """``alarm_gap_s``: the shortest time between two alarms of one event. Objects that
    join meanwhile are announced together by the next one (if still there), so a
    crowd, or a camera so overloaded that its tracks break, cannot flood the disk
    with snapshots."""

    def __init__(self, quiet_s: float = 1.0, alarm_gap_s: float = 0.0) -> None:
        self.quiet_s = quiet_s
        self.alarm_gap_s = alarm_gap_s
        self.current: MotionEvent | None = None
        self._last_motion_s = 0.0
        self._next_id = 1

    def update(self, frame: int, time_s: float, detections: Sequence[Detection]) -> AlarmUpdate:
        """Feed one frame's confirmed detections; says whether an event started or ended."""
        ended = None
        if detections:
            self._last_motion_s = time_s
            area = sum(d.area for d in detections)
            started = None
            if self.current is None:
                self.current = MotionEvent(self._next_id, frame, time_s, frame, time_s)
                self._next_id += 1
                started = self.current
            event = self.current
            event.end_frame, event.end_time_s = frame, time_s
            seen = {d.track_id for d in detections if d.track_id is not None}
            newcomers: tuple[int, ...] = ()
            if not started and time_s - event.last_alarm_s >= self.alarm_gap_s:
                newcomers = tuple(sorted(seen - event.announced))
            if started or newcomers:
                event.announced.update(seen)
                event.last_alarm_s = time_s
            event.track_ids.update(seen)
            if area > event.max_area:
                event.max_area, event.peak_frame = area, frame
            return AlarmUpdate(started=started, newcomers=newcomers)
        if self.current is not None and time_s - self._last_motion_s >= self.quiet_s:
            ended, self.current = self.current, None
        return AlarmUpdate(ended=ended)

    def finish(self) -> MotionEvent | None:
        """End the open event, if any (the video or the watch is over)."""
        ended, self.current = self.current, None
        return ended
