"""The demo camera's scene: a street with people walking and cars passing, looped.

Still synthetic, with exact truth: each passer-by goes in a straight line on the ground
at a steady pace, is drawn from a sprite whose box is what it covers, and ``truth`` gives
that box and the speed of its middle in the picture for any frame. The street is painted
once (``demo_street``), people and cars once per pose and size (``demo_sprites``); a frame
is a copy of the street, the sprites nearest last, and a little camera noise.

Quiet gaps of more than two seconds (``GAP_S``) part who comes by (someone walking, a
car, two people who pass each other, someone crossing the road, a car), so an activated
demo camera raises a new alarm, with its snapshot, for each; the loop starts and ends
with an empty street, so it joins without a jump.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cache

import cv2
import numpy as np

from app.sources.demo_sprites import (
    Car,
    Person,
    Sprite,
    car_sprite,
    gait_pose,
    person_sprite,
)
from app.sources.demo_street import CAMERA, HEIGHT, WIDTH, paint_street
from app.sources.synthetic import TruthObject
from app.vision.detections import Box
from app.vision.types import Image

FPS = 15.0
NOISE_SIGMA = 2.0
"""Camera noise, grey levels (each colour on its own)."""
NOISE_ROWS = 61
"""Spare rows of the pre-drawn noise: each frame takes its rows from another offset."""
GAP_S = 2.7
"""Quiet seconds between passings: more than the 2 s that end an event."""
MIN_VISIBLE_FRACTION = 0.5
"""An object partly out of view counts as truth once this share of its box is in view
(as ``synthetic.Scene`` counts it)."""


@dataclass(frozen=True)
class Passing:
    """Someone or a car going from ``start`` to ``end`` (metres along the street, and
    from the camera) at ``speed_m_s``, setting off ``start_s`` into the loop."""

    look: Person | Car
    start: tuple[float, float]
    end: tuple[float, float]
    speed_m_s: float
    start_s: float

    @property
    def length_m(self) -> float:
        return math.dist(self.start, self.end)

    @property
    def end_s(self) -> float:
        return self.start_s + self.length_m / self.speed_m_s

    def ground_at(self, time_s: float) -> tuple[float, float] | None:
        """Where on the ground it is at ``time_s``; None before it sets off or after."""
        if not self.start_s <= time_s <= self.end_s:
            return None
        share = (time_s - self.start_s) * self.speed_m_s / self.length_m
        (x0, d0), (x1, d1) = self.start, self.end
        return (x0 + share * (x1 - x0), d0 + share * (d1 - d0))

    def middle_at(self, time_s: float) -> tuple[float, float]:
        """Where its middle (half its height above the ground) shows in the picture."""
        x_m, depth_m = self.ground_at(time_s) or self.start
        x, y = CAMERA.ground_to_image(x_m, depth_m)
        return (x, y - 0.5 * self.look.height_m * CAMERA.px_per_m(depth_m))

    def speed_px_s(self, time_s: float) -> float:
        """How fast its middle moves in the picture (it changes as it comes nearer)."""
        dt = 0.5 / FPS
        before = self.middle_at(max(self.start_s, time_s - dt))
        after = self.middle_at(min(self.end_s, time_s + dt))
        return math.dist(before, after) / (2 * dt)

    def sprite_at(self, time_s: float) -> tuple[Sprite, int, int] | None:
        """Its sprite and the sprite's top-left corner in the picture at ``time_s``."""
        where = self.ground_at(time_s)
        if where is None:
            return None
        x_m, depth_m = where
        facing_left = self.end[0] < self.start[0]
        px_m = CAMERA.px_per_m(depth_m)
        if isinstance(self.look, Person):
            walked = (time_s - self.start_s) * self.speed_m_s
            height = round(self.look.height_m * px_m)
            sprite = person_sprite(self.look, height, gait_pose(walked), facing_left)
        else:
            sprite = car_sprite(self.look, round(self.look.length_m * px_m), facing_left)
        x, y = CAMERA.ground_to_image(x_m, depth_m)
        return sprite, round(x - sprite.anchor[0]), round(y - sprite.anchor[1])


# People on the far pavement walk about 16.5 m from the camera, on the near one about
# 8.3 m; cars keep 12.9 m (the far lane) or 10.6 m (the near one).
YELLOW_JACKET = Person(top=(40, 185, 235), legs=(95, 60, 40))
RED_COAT = Person(
    top=(50, 45, 200), legs=(40, 35, 35), coat=True, hair=(25, 60, 120), height_m=1.68
)
WHITE_SHIRT = Person(
    top=(225, 225, 230),
    legs=(120, 75, 45),
    backpack=(60, 115, 40),
    skin=(95, 125, 170),
    hair=(25, 25, 30),
)
GREEN_JACKET = Person(top=(80, 150, 60), legs=(110, 150, 170), hair=(40, 70, 120))
RED_CAR = Car(body=(45, 45, 205))
WHITE_CAR = Car(body=(232, 232, 235), length_m=4.5, height_m=1.5)


def street_passings() -> tuple[Passing, ...]:
    """Who passes, when: one after another, a gap of ``GAP_S`` between."""
    plan: list[Passing] = []

    def after_gap() -> float:
        return max(p.end_s for p in plan) + GAP_S

    plan.append(Passing(YELLOW_JACKET, (-5.3, 8.1), (5.3, 8.1), 1.45, 0.8))
    plan.append(Passing(RED_CAR, (10.5, 12.9), (-10.5, 12.9), 4.6, after_gap()))
    pair = after_gap()
    plan.append(Passing(RED_COAT, (10.5, 16.6), (-10.5, 16.6), 1.7, pair))
    plan.append(Passing(WHITE_SHIRT, (-5.6, 8.6), (5.6, 8.6), 1.35, pair + 1.5))
    plan.append(Passing(GREEN_JACKET, (-5.7, 8.3), (10.4, 16.4), 1.6, after_gap()))
    plan.append(Passing(WHITE_CAR, (-9.0, 10.6), (9.0, 10.6), 5.5, after_gap()))
    return tuple(plan)


@dataclass(frozen=True)
class StreetScene:
    """The demo's street, ``frames`` long at ``fps``: ``frame`` and ``truth`` as
    ``synthetic.Scene`` gives them."""

    passings: tuple[Passing, ...]
    frames: int
    name: str = "demo"
    fps: float = FPS
    size: tuple[int, int] = (WIDTH, HEIGHT)
    noise_sigma: float = NOISE_SIGMA
    seed: int = 11
    street: Image = field(repr=False, compare=False, default_factory=paint_street)

    def frame(self, index: int) -> Image:
        """The BGR frame at ``index`` (0 <= index < frames)."""
        image = self.street.copy()
        placed = self._placed(index)
        # The farthest first: the one whose feet are higher in the picture.
        placed.sort(key=lambda p: p[3] + p[1].anchor[1])
        for _, sprite, left, top in placed:
            sprite.paste(image, left, top)
        if self.noise_sigma > 0:
            brighter, darker = camera_noise(self.seed, self.noise_sigma, self.size)
            offset = (index * 37) % NOISE_ROWS
            rows = slice(offset, offset + self.size[1])
            cv2.add(image, brighter[rows], dst=image)
            cv2.subtract(image, darker[rows], dst=image)
        return image

    def truth(self, index: int) -> list[TruthObject]:
        """Every object at least half in view in frame ``index`` (``MIN_VISIBLE_FRACTION``):
        the box of what its sprite covers in view (shadow included), and the speed of its
        middle."""
        time_s = index / self.fps
        return [
            TruthObject(i, box, self.passings[i].speed_px_s(time_s))
            for i, box, share in self.in_view(index)
            if share >= MIN_VISIBLE_FRACTION
        ]

    def in_view(self, index: int) -> list[tuple[int, Box, float]]:
        """Every object with any part in view in frame ``index``: its index, the box of
        what is in view and the share of its whole box that is."""
        out = []
        for i, sprite, left, top in self._placed(index):
            w, h = sprite.size
            x0, y0 = max(0, left), max(0, top)
            x1, y1 = min(self.size[0], left + w), min(self.size[1], top + h)
            if x1 > x0 and y1 > y0:
                share = (x1 - x0) * (y1 - y0) / (w * h)
                out.append((i, Box(x0, y0, x1 - x0, y1 - y0), share))
        return out

    def on_partly_visible(self, index: int, box: Box) -> bool:
        """Whether most of ``box`` lies on an object too little in view to count as truth
        in frame ``index``: a detection there is neither right nor wrong (one entering
        or leaving the picture), as scoring against ``truth`` should take it."""
        counted = {t.object_index for t in self.truth(index)}
        for i, visible, _ in self.in_view(index):
            if i not in counted:
                w = min(box.x + box.w, visible.x + visible.w) - max(box.x, visible.x)
                h = min(box.y + box.h, visible.y + visible.h) - max(box.y, visible.y)
                if w > 0 and h > 0 and 2 * w * h >= box.area:
                    return True
        return False

    def _placed(self, index: int) -> list[tuple[int, Sprite, int, int]]:
        """Each object set off and not yet arrived: its index, sprite and corner."""
        time_s = index / self.fps
        out = []
        for i, passing in enumerate(self.passings):
            placed = passing.sprite_at(time_s)
            if placed is not None:
                out.append((i, *placed))
        return out


@cache
def camera_noise(seed: int, sigma: float, size: tuple[int, int]) -> tuple[Image, Image]:
    """Noise drawn once, as what it adds and what it takes away (uint8, so a frame gets
    it by two saturating OpenCV calls), ``NOISE_ROWS`` taller than the picture."""
    w, h = size
    noise = np.round(np.random.default_rng(seed).normal(0.0, sigma, (h + NOISE_ROWS, w, 3)))
    return np.clip(noise, 0, 255).astype(np.uint8), np.clip(-noise, 0, 255).astype(np.uint8)


@cache
def demo_street_scene() -> StreetScene:
    """The demo camera's scene (painted once per process, shared by every demo camera)."""
    passings = street_passings()
    loop_s = max(p.end_s for p in passings) + GAP_S
    return StreetScene(passings, frames=round(loop_s * FPS))
