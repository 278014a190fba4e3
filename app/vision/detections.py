"""The one value that flows from detector to tracker, annotator, events and storage."""

from __future__ import annotations

from dataclasses import dataclass, replace

# The frame's edges a blob touches (Detection.edges, bits): there the object may go on
# out of view, and its box shows only part of it.
LEFT, RIGHT, TOP, BOTTOM = 1, 2, 4, 8


@dataclass(frozen=True, slots=True)
class Box:
    """An axis-aligned rectangle in pixels of the input frame."""

    x: int
    y: int
    w: int
    h: int

    @property
    def area(self) -> int:
        return self.w * self.h

    @property
    def center(self) -> tuple[float, float]:
        return (self.x + self.w / 2.0, self.y + self.h / 2.0)

    @property
    def bottom_center(self) -> tuple[float, float]:
        """Where an upright object touches the ground: what calibration maps."""
        return (self.x + self.w / 2.0, float(self.y + self.h))

    def overlaps(self, other: Box) -> bool:
        """Whether the two share a pixel."""
        return (
            self.x < other.x + other.w
            and other.x < self.x + self.w
            and self.y < other.y + other.h
            and other.y < self.y + self.h
        )

    def iou(self, other: Box) -> float:
        ix = max(0, min(self.x + self.w, other.x + other.w) - max(self.x, other.x))
        iy = max(0, min(self.y + self.h, other.y + other.h) - max(self.y, other.y))
        inter = ix * iy
        union = self.area + other.area - inter
        return inter / union if union > 0 else 0.0

    def as_list(self) -> list[int]:
        return [self.x, self.y, self.w, self.h]


@dataclass(frozen=True, slots=True)
class Detection:
    """A moving object in one frame.

    The detector fills box, centroid, area and the frame edges the object
    touches; the tracker adds the track id, the distance moved since the
    object's previous sighting and its smoothed speed; calibration adds
    ground-plane values when the camera is calibrated.
    """

    box: Box
    centroid: tuple[float, float]
    area: float
    edges: int = 0
    """LEFT | RIGHT | TOP | BOTTOM: the frame's edges its blob touches."""
    track_id: int | None = None
    distance_px: float = 0.0
    speed_px_s: float = 0.0
    ground_xy_m: tuple[float, float] | None = None
    range_m: float | None = None
    speed_m_s: float | None = None

    def with_track(self, track_id: int, distance_px: float, speed_px_s: float) -> Detection:
        # Built directly: dataclasses.replace costs several times more, on every
        # object of every frame.
        return Detection(
            box=self.box,
            centroid=self.centroid,
            area=self.area,
            edges=self.edges,
            track_id=track_id,
            distance_px=distance_px,
            speed_px_s=speed_px_s,
            ground_xy_m=self.ground_xy_m,
            range_m=self.range_m,
            speed_m_s=self.speed_m_s,
        )

    def with_ground(
        self, ground_xy_m: tuple[float, float], range_m: float, speed_m_s: float | None
    ) -> Detection:
        return replace(self, ground_xy_m=ground_xy_m, range_m=range_m, speed_m_s=speed_m_s)
