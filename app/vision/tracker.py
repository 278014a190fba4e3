"""Tracking: persistent ids, per-frame distance and smoothed velocity.

Each track predicts where its object will be (constant velocity), detections
are assigned to predictions by minimum total distance (Hungarian algorithm),
and a track survives a few frames without a detection so objects that cross
or hide briefly keep their id. When two tracked objects merge into one blob
(they cross), the blob is split back into one detection per track at the
predicted positions, so neither object is lost for the frames of the
crossing.

A track is reported once it has been seen ``min_hits`` times and has moved
away from where it was born, or seen ``min_hits_in_place`` times if it has
not (Motion's ``minimum_motion_frames``, kept short for what moves): swaying
leaves and start-up ghosts flicker in place, objects move on. Nor is a track
reported while it only jumps: from one frame to the next (at 15 frames a
second or more) its box leaves the last one behind. A raindrop's streak is as
long as its fall while the shutter is open, shorter than its fall from one
frame to the next; an object's own length keeps its boxes overlapping unless
it is tiny or extremely fast. Velocity is a
Theil-Sen line through the recent centroids, so a frame or two of a blob
splitting or dragging a remnant along does not tilt it; while the frame's edge
cuts an object (it enters or leaves), through the side of its box that is
whole, which moves with it where the centroid of its visible part lags.
"""

from __future__ import annotations

import math
import statistics
from collections import deque
from dataclasses import dataclass, field, replace
from typing import TypeVar

import numpy as np
from scipy.optimize import linear_sum_assignment

from app.vision.detections import Box, Detection
from app.vision.kinematics import VelocityWindow, sighting_position, speed, step_length

Point = tuple[float, float]
Distance = TypeVar("Distance", float, np.ndarray)

DISALLOWED = 1e9
"""The cost of a pair outside the gate, for the assignment solver."""
SMALL_ASSIGNMENT = 64
"""Up to this many (detection, track) pairs, the gate is checked in plain Python."""
REFERENCE_FRAME_S = 1 / 25
"""The frame period at which ``max_missed`` and the gate's growth per frame unseen are
given: where frames come faster (``Tracker.frames_per_reference``) they stand for as long,
not for as many frames."""
MAX_FRAMES_PER_REFERENCE = 10.0
"""Frames per 25-fps frame counted at most (250 fps)."""
RATE_SLACK = 1.1
"""A rate up to this many times 25 fps counts as 25 (a live camera's times jitter)."""
PERIODS = 16
"""Recent intervals between frames whose median is the frame period."""


@dataclass
class Track:
    key: int
    box: Box
    sightings: VelocityWindow
    """Recent sightings (times and positions), for the velocity fit."""
    track_id: int = 0
    """The public id, given when the track is confirmed, so ids count up without gaps."""
    hits: int = 1
    missed: int = 0
    trail: deque[Point] = field(default_factory=lambda: deque(maxlen=64))
    """Recent centroids."""
    velocity: Point = (0.0, 0.0)
    origin: Point = (0.0, 0.0)
    """Where the track was first seen."""
    moved: bool = False
    """Whether it has ever been further than ``in_place_px`` from its origin."""
    jumped: bool = False
    """Whether it was seen in two frames in a row (``jump_gap_s`` apart or less) with boxes
    that do not overlap..."""
    overlapped: bool = False
    """... and whether with boxes that do."""
    extent: tuple[float, float] = (0.0, 0.0)
    """Width and height of the object as lately seen in one piece: the largest of its
    one-blob boxes, each one-blob sighting forgetting ``extent_forget`` of what it was
    beyond the newest (sightings of joined pieces leave it as it is)."""

    @property
    def last_centroid(self) -> Point:
        return self.trail[-1]

    def predict(self, time_s: float) -> Point:
        dt = time_s - self.sightings.last_time
        x, y = self.last_centroid
        return (x + self.velocity[0] * dt, y + self.velocity[1] * dt)


@dataclass(frozen=True)
class TrackerConfig:
    max_missed: int = 8
    """Frames a track coasts without a detection before it is dropped (0.32 s at 25 fps,
    0.8 s at 10); at higher rates, as long as they last at 25 fps: at 60 fps, someone
    hidden by a post for a fifth of a second is 12 frames unseen."""
    min_hits: int = 2
    """Sightings before a track is reported (drops one-frame flickers)."""
    min_hits_in_place: int = 3
    """Sightings before a track that has stayed where it was born is reported.

    Leaves, ripples and start-up ghosts flicker in place for a frame or two;
    an object moves on, and is reported at ``min_hits`` as soon as it does.
    """
    in_place_px: float = 2.0
    """Distance from its first centroid within which a track counts as in place."""
    jump_gap_s: float = 0.07
    """Seconds: sightings in frames in a row at most this far apart (15 frames a second or
    more) whose boxes do not overlap are a jump; a track whose sightings only jump is not
    reported (rain streaks). Further apart, or across a frame the track coasted over, a
    fast object (a motorbike at 10 fps) may well have moved past its own length: such
    sightings tell nothing either way."""
    gate_px: float = 25.0
    """Largest jump (beyond the object's own size) a detection may make to join a track."""
    together_share: float = 0.25
    """Tracks in one blob whose velocities differ by less than this share of the faster
    one's speed move as one: the blob is one object's, not a crossing to split."""
    smoothing_window_s: float = 0.6
    """Span of history the velocity fit looks at."""
    extent_forget: float = 0.02
    """The share of a track's remembered size it forgets per one-blob sighting (a half-life of
    about 35 frames), so that it follows an object that goes away from the camera."""
    piece_slack: float = 0.1
    """A left-over blob joins a track's blob when together they fit the track's
    remembered size grown by this share and 2 px: pieces of one object, not another
    object beside it (see ``_join_pieces``)."""
    max_objects: int = 64
    """Largest blobs kept per frame: past this a frame is noise, and assignment cost grows."""


class Tracker:
    def __init__(self, config: TrackerConfig | None = None) -> None:
        self.config = config or TrackerConfig()
        self.tracks: dict[int, Track] = {}
        self._next_key = 1
        self._next_id = 1
        self._periods: deque[float] = deque(maxlen=PERIODS)
        """Recent intervals between the frames' times (positive ones)."""
        self._last_time: float | None = None
        self._per_reference = 1.0
        """``frames_per_reference`` as of this frame (the gates read it)."""

    def update(self, detections: list[Detection], time_s: float) -> list[Detection]:
        """Assign ids; return the detections of confirmed tracks, with distance and speed."""
        if len(detections) > self.config.max_objects:
            detections = sorted(detections, key=lambda d: d.area, reverse=True)
            detections = detections[: self.config.max_objects]
        tracks = list(self.tracks.values())
        predictions = [track.predict(time_s) for track in tracks]
        merged, detections, tracks, predictions = self._split_merged(
            detections, tracks, predictions
        )
        if self._last_time is not None and time_s > self._last_time:
            self._periods.append(time_s - self._last_time)
        self._last_time = time_s
        self._per_reference = self.frames_per_reference()
        matches, unmatched = self._assign(detections, tracks, predictions)
        assigned, unmatched = self._join_pieces(
            [(track, detections[i]) for i, track in matches], detections, unmatched, time_s
        )

        reported: list[Detection] = []
        matched = set()
        # A crossing's pieces are cut from predictions: they teach no size.
        for track, detection, one_blob in [(t, d, False) for t, d in merged] + assigned:
            matched.add(track.key)
            extended = self._extend(track, detection, time_s, one_blob)
            if extended is not None:
                reported.append(extended)
        for track in self.tracks.values():
            if track.key not in matched:
                track.missed += 1
        for track in list(self.tracks.values()):
            # Past the count, rounding aside (at 50 fps, 16 frames last 8 at 25 fps).
            if track.missed > self.config.max_missed * self._per_reference + 1e-6:
                del self.tracks[track.key]
        for det_index in unmatched:
            track = self._start(detections[det_index], time_s)
            if track.track_id:
                reported.append(detections[det_index].with_track(track.track_id, 0.0, 0.0))
        reported.sort(key=lambda d: d.track_id or 0)
        return reported

    def trails(self) -> dict[int, list[Point]]:
        """Recent centroids of every live, confirmed track (for drawing)."""
        return {
            track.track_id: list(track.trail) for track in self.tracks.values() if track.track_id
        }

    def reset(self) -> None:
        self.tracks.clear()
        self._next_key = 1
        self._next_id = 1
        self._periods.clear()
        self._last_time = None
        self._per_reference = 1.0

    def _assign(
        self, detections: list[Detection], tracks: list[Track], predictions: list[Point]
    ) -> tuple[list[tuple[int, Track]], list[int]]:
        if not detections:
            return [], []
        if not tracks:
            return [], list(range(len(detections)))
        allowed = (
            self._allowed_pairs(detections, tracks, predictions)
            if len(detections) * len(tracks) <= SMALL_ASSIGNMENT
            else self._allowed_pairs_vectorised(detections, tracks, predictions)
        )
        rows = [d for d, _, _ in allowed]
        cols = [t for _, t, _ in allowed]
        if len(set(rows)) < len(rows) or len(set(cols)) < len(cols):
            # Rivals: the pairing with the least total distance among the allowed ones.
            costs = np.full((len(detections), len(tracks)), DISALLOWED)
            for d_index, t_index, cost in allowed:
                costs[d_index, t_index] = cost
            best_rows, best_cols = linear_sum_assignment(costs)
            keep = costs[best_rows, best_cols] < DISALLOWED
            rows, cols = best_rows[keep].tolist(), best_cols[keep].tolist()
        # Otherwise no detection or track has a rival: every allowed pair is the best.
        matched_rows = set(rows)
        matches = [(r, tracks[c]) for r, c in zip(rows, cols, strict=True)]
        return matches, [i for i in range(len(detections)) if i not in matched_rows]

    def frames_per_reference(self) -> float:
        """Frames in the time of one at 25 fps, by the median of the recent intervals
        between frames: 1 at 25 fps or less (the counts are frames there), 2.4 at 60.
        The median, so that a live camera's jittery times count as its rate."""
        if not self._periods:
            return 1.0
        per_reference = REFERENCE_FRAME_S / statistics.median(self._periods)
        if per_reference <= RATE_SLACK:
            return 1.0
        return min(per_reference, MAX_FRAMES_PER_REFERENCE)

    def _gate(self, size: Distance, missed: Distance) -> Distance:
        """How far a detection may be from a track's prediction (floats or arrays): the
        gate widens with the object's size and with each frame it went unseen, counted as
        frames at 25 fps where frames come faster (``frames_per_reference``)."""
        return self.config.gate_px + size * (0.5 + 0.25 * missed / self._per_reference)

    def _allowed_pairs(
        self, detections: list[Detection], tracks: list[Track], predictions: list[Point]
    ) -> list[tuple[int, int, float]]:
        """(detection, track, distance) within the gate, in plain Python: a frame has a
        handful of objects, where NumPy's per-call overhead (a dozen calls) costs several
        times the arithmetic on a camera gone cold."""
        track_sizes = [max(t.box.w, t.box.h) for t in tracks]
        allowed = []
        for d_index, detection in enumerate(detections):
            x, y = detection.centroid
            detection_size = max(detection.box.w, detection.box.h)
            for t_index, (px, py) in enumerate(predictions):
                cost = math.hypot(x - px, y - py)
                size = max(detection_size, track_sizes[t_index])
                if cost <= self._gate(size, tracks[t_index].missed):
                    allowed.append((d_index, t_index, cost))
        return allowed

    def _allowed_pairs_vectorised(
        self, detections: list[Detection], tracks: list[Track], predictions: list[Point]
    ) -> list[tuple[int, int, float]]:
        """The same for a crowded frame (noise, many coasting tracks), with NumPy."""
        det_xy = np.array([d.centroid for d in detections])
        det_size = np.array([max(d.box.w, d.box.h) for d in detections], dtype=np.float64)
        track_size = np.array([max(t.box.w, t.box.h) for t in tracks], dtype=np.float64)
        missed = np.array([t.missed for t in tracks], dtype=np.float64)
        offset = det_xy[:, None, :] - np.array(predictions)[None, :, :]
        cost = np.hypot(offset[..., 0], offset[..., 1])
        size = np.maximum(det_size[:, None], track_size[None, :])
        rows, cols = np.nonzero(cost <= self._gate(size, missed[None, :]))
        pairs = zip(rows.tolist(), cols.tolist(), strict=True)
        return [(d, t, float(cost[d, t])) for d, t in pairs]

    def _split_merged(
        self, detections: list[Detection], tracks: list[Track], predictions: list[Point]
    ) -> tuple[list[tuple[Track, Detection]], list[Detection], list[Track], list[Point]]:
        """Objects that cross merge into one blob: give each of their tracks its own piece.

        A blob is a merge when it holds the predicted centres of two or more
        confirmed tracks that were each seen last frame (and no other blob
        holds them) and that do not move as one (``_move_as_one``). Each
        track then gets its own box at its predicted position, cut to the
        blob. Returns those (track, piece) pairs and what is left for
        ordinary assignment.
        """
        candidates = [
            (track, predicted)
            for track, predicted in zip(tracks, predictions, strict=True)
            if track.track_id and track.missed == 0
        ]
        if len(candidates) < 2:
            return [], detections, tracks, predictions
        holders: dict[int, list[int]] = {}
        for t_index, (_, predicted) in enumerate(candidates):
            holding = [i for i, det in enumerate(detections) if _contains(det.box, predicted)]
            if len(holding) == 1:
                holders.setdefault(holding[0], []).append(t_index)
        merged: list[tuple[Track, Detection]] = []
        used_detections: set[int] = set()
        used_tracks: set[int] = set()
        for det_index, t_indices in holders.items():
            det = detections[det_index]
            inside = [candidates[i] for i in t_indices]
            if len(inside) < 2 or self._move_as_one(inside):
                continue
            share = det.area / sum(t.box.area for t, _ in inside)
            for track, predicted in inside:
                box = _clip(_centred(track.box, predicted), det.box)
                # Its share of the blob's pixels, which its piece of the box must hold.
                area = min(track.box.area * share, float(box.area))
                merged.append((track, Detection(box, predicted, area)))
                used_tracks.add(track.key)
            used_detections.add(det_index)
        if not merged:
            return [], detections, tracks, predictions
        rest = [
            (t, p) for t, p in zip(tracks, predictions, strict=True) if t.key not in used_tracks
        ]
        return (
            merged,
            [d for i, d in enumerate(detections) if i not in used_detections],
            [t for t, _ in rest],
            [p for _, p in rest],
        )

    def _move_as_one(self, inside: list[tuple[Track, Point]]) -> bool:
        """Whether two of these tracks move as one (their velocities differ by under
        ``together_share`` of the faster one's speed): two pieces of one object (it
        split for a few frames, say, as it came into view) that have joined up again,
        not objects that cross or overtake. Coasting each on its prediction would
        report one object as two, with shrinking boxes and frozen speeds."""
        for index, (first, _) in enumerate(inside):
            for second, _ in inside[index + 1 :]:
                apart = math.dist(first.velocity, second.velocity)
                faster = max(speed(first.velocity), speed(second.velocity))
                if apart < self.config.together_share * faster:
                    return True
        return False

    def _join_pieces(
        self,
        pairs: list[tuple[Track, Detection]],
        detections: list[Detection],
        unmatched: list[int],
        time_s: float,
    ) -> tuple[list[tuple[Track, Detection, bool]], list[int]]:
        """Blobs that no track took and that are pieces of a tracked object, joined to its
        blob: where part of an object matches the background (a grey coat on a grey
        wall) its blob breaks in two, and the piece would start a second track beside
        the first. A piece joins a confirmed track's blob when the two together fit the
        object's remembered size (``Track.extent``) but for ``piece_slack``: an object
        of its own beside or behind a tracked one, or stepping out of it, makes it
        wider than that. Each piece goes to the nearest such track (its prediction),
        biggest pieces first. Returns each track's detection with whether it is one
        blob, and the blobs left over."""
        joined = [(track, detection, True) for track, detection in pairs]
        if not unmatched:  # Most frames.
            return joined, unmatched
        predicted = [track.predict(time_s) for track, _ in pairs]
        left = []
        grow = 1.0 + self.config.piece_slack
        for index in sorted(unmatched, key=lambda i: -detections[i].area):
            piece = detections[index]
            best: tuple[int, Detection] | None = None
            nearest = math.inf
            for slot, (track, detection, _) in enumerate(joined):
                if not track.track_id:
                    continue
                together = _together(detection, piece)
                width, height = track.extent
                fits = together.box.w <= grow * width + 2.0
                fits = fits and together.box.h <= grow * height + 2.0
                distance = math.dist(predicted[slot], piece.centroid)
                if fits and distance < nearest:
                    best, nearest = (slot, together), distance
            if best is None:
                left.append(index)
                continue
            slot, together = best
            joined[slot] = (joined[slot][0], together, False)
        return joined, sorted(left)

    def _extend(
        self, track: Track, detection: Detection, time_s: float, one_blob: bool
    ) -> Detection | None:
        """``one_blob``: the detection is one blob, from which the track learns its size
        (``Track.extent``)."""
        position = sighting_position(detection)
        step = step_length(track.sightings.last_position, position)
        if not track.missed and time_s - track.sightings.last_time <= self.config.jump_gap_s:
            if track.box.overlaps(detection.box):
                track.overlapped = True
            else:
                track.jumped = True
        track.hits += 1
        track.missed = 0
        track.box = detection.box
        if one_blob:
            track.extent = self._remembered_size(track.extent, detection.box)
        track.sightings.add(time_s, position)
        track.trail.append(detection.centroid)
        track.moved = track.moved or math.dist(detection.centroid, track.origin) > (
            self.config.in_place_px
        )
        track.velocity = track.sightings.velocity(time_s)
        self._confirm_if_due(track)
        if not track.track_id:
            return None
        return detection.with_track(track.track_id, step, speed(track.velocity))

    def _start(self, detection: Detection, time_s: float) -> Track:
        track = Track(
            key=self._next_key,
            box=detection.box,
            origin=detection.centroid,
            sightings=VelocityWindow(self.config.smoothing_window_s),
            extent=(detection.box.w, detection.box.h),
        )
        self._next_key += 1
        track.sightings.add(time_s, sighting_position(detection))
        track.trail.append(detection.centroid)
        self.tracks[track.key] = track
        self._confirm_if_due(track)
        return track

    def _remembered_size(self, extent: tuple[float, float], box: Box) -> tuple[float, float]:
        keep = 1.0 - self.config.extent_forget
        return (max(float(box.w), keep * extent[0]), max(float(box.h), keep * extent[1]))

    def _confirm_if_due(self, track: Track) -> None:
        needed = self.config.min_hits if track.moved else self.config.min_hits_in_place
        jumps_only = track.jumped and not track.overlapped
        if (
            not track.track_id
            and not jumps_only
            and track.hits >= max(self.config.min_hits, needed)
        ):
            track.track_id = self._next_id
            self._next_id += 1


def _together(first: Detection, second: Detection) -> Detection:
    """Two blobs as one object's: the box around both, their pixels, their centroid."""
    x0, y0 = min(first.box.x, second.box.x), min(first.box.y, second.box.y)
    x1 = max(first.box.x + first.box.w, second.box.x + second.box.w)
    y1 = max(first.box.y + first.box.h, second.box.y + second.box.h)
    area = first.area + second.area
    weights = (first.area, second.area) if area > 0 else (1.0, 1.0)
    centroid = (
        (first.centroid[0] * weights[0] + second.centroid[0] * weights[1]) / sum(weights),
        (first.centroid[1] * weights[0] + second.centroid[1] * weights[1]) / sum(weights),
    )
    return Detection(Box(x0, y0, x1 - x0, y1 - y0), centroid, area, first.edges | second.edges)


def _contains(box: Box, point: Point) -> bool:
    return box.x <= point[0] <= box.x + box.w and box.y <= point[1] <= box.y + box.h


def _centred(box: Box, centre: Point) -> Box:
    return replace(box, x=round(centre[0] - box.w / 2), y=round(centre[1] - box.h / 2))


def _clip(box: Box, bounds: Box) -> Box:
    x0, y0 = max(box.x, bounds.x), max(box.y, bounds.y)
    x1 = min(box.x + box.w, bounds.x + bounds.w)
    y1 = min(box.y + box.h, bounds.y + bounds.h)
    return Box(x0, y0, max(1, x1 - x0), max(1, y1 - y0))
