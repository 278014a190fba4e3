"""People and cars for the demo scene, drawn once per pose and size, then pasted.

A sprite is drawn three times larger than shown and shrunk (smooth edges), shaded as if
rounded and lit from the upper left, with a soft contact shadow under it. It is cropped to
what it covers: its box is the object's exact box in the picture wherever it is pasted.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import cv2
import numpy as np

from app.vision.types import AnyArray, Image

SUPERSAMPLE = 3
MIN_ALPHA = 0.1
"""A sprite's pixels cover at least this much of what is behind them, or nothing: so its
box is where it changes the picture."""
SHADOW_ALPHA = 0.4
GAIT_POSES = 16
"""Poses drawn per stride (two steps)."""
STRIDE_M = 1.4
"""Ground covered by one stride: a walker's pose follows the distance walked, so the feet
do not slide."""

BGR = tuple[int, int, int]
Ink = float | tuple[float, ...]
"""What a shape is drawn with: a colour on the colour canvas, a coverage on the others."""


@dataclass(frozen=True)
class Person:
    """How someone looks: colours (BGR) of what they wear."""

    top: BGR
    legs: BGR
    skin: BGR = (120, 160, 215)
    hair: BGR = (30, 40, 60)
    shoes: BGR = (35, 35, 40)
    coat: bool = False
    """A coat down to the knees over the legs."""
    backpack: BGR | None = None
    height_m: float = 1.75


@dataclass(frozen=True)
class Car:
    body: BGR
    length_m: float = 4.2
    height_m: float = 1.45


@dataclass(frozen=True)
class Sprite:
    colour: AnyArray
    """H x W x 3 uint8, premultiplied by the coverage."""
    keep: AnyArray
    """H x W x 1 uint8: how much of what is behind shows through, 0..255 (255: all of it,
    outside the object; otherwise at most 255 * (1 - MIN_ALPHA))."""
    anchor: tuple[float, float]
    """Where the object meets the ground (x, y) within the sprite: under the hips, or the
    middle of a car's length."""

    @property
    def size(self) -> tuple[int, int]:
        """Width and height: its box's, wherever it is pasted."""
        return (self.keep.shape[1], self.keep.shape[0])

    def paste(self, image: Image, left: int, top: int) -> None:
        """Draw over ``image`` (uint8 BGR, in place) with the sprite's corner at (left, top)."""
        w, h = self.size
        x0, y0 = max(0, left), max(0, top)
        x1, y1 = min(image.shape[1], left + w), min(image.shape[0], top + h)
        if x1 <= x0 or y1 <= y0:
            return
        part = (slice(y0 - top, y1 - top), slice(x0 - left, x1 - left))
        region = image[y0:y1, x0:x1]
        behind = (region * self.keep[part].astype(np.uint16) + 127) // 255
        region[:] = np.minimum(behind + self.colour[part], 255)


def gait_pose(distance_m: float) -> int:
    """The pose (0..GAIT_POSES-1) of someone who has walked ``distance_m``."""
    return math.floor(distance_m / STRIDE_M * GAIT_POSES) % GAIT_POSES


@cache
def person_sprite(look: Person, height_px: int, pose: int, facing_left: bool) -> Sprite:
    """Someone ``height_px`` tall walking, seen from the side, in pose ``pose``."""
    h = height_px * SUPERSAMPLE
    canvas = _Canvas(round(0.7 * h), round(1.1 * h))
    hip_x = canvas.width / 2
    phase = 2 * math.pi * pose / GAIT_POSES
    legs = [_leg(h, phase), _leg(h, phase + math.pi)]  # Near, far: relative to the hip.
    lowest = max(max(p[1] for p in leg) for leg in legs)
    ground = 1.02 * h
    hip = (hip_x, ground - lowest)
    shoulder = (hip[0] + 0.025 * h, hip[1] - 0.3 * h)
    canvas.ellipse((hip_x, ground), (0.2 * h, 0.035 * h), (0, 0, 0), SHADOW_ALPHA)
    shade = 0.72  # The far limbs, in the body's shadow.
    canvas.arm(look, shoulder, h, phase, shade)
    for leg, tint in ((legs[1], shade), (legs[0], 1.0)):
        knee, ankle, toe = ((hip[0] + x, hip[1] + y) for x, y in leg)
        canvas.limb([hip, knee, ankle], 0.085 * h, _tint(look.legs, tint))
        canvas.limb([ankle, toe], 0.05 * h, _tint(look.shoes, tint))
    if look.coat:
        hem = hip[1] + 0.2 * h
        canvas.polygon(
            [
                (shoulder[0] - 0.08 * h, shoulder[1]),
                (shoulder[0] + 0.075 * h, shoulder[1]),
                (hip[0] + 0.12 * h, hem),
                (hip[0] - 0.12 * h, hem),
            ],
            look.top,
        )
    if look.backpack is not None:
        canvas.rounded_box(
            (shoulder[0] - 0.16 * h, shoulder[1] + 0.02 * h), 0.09 * h, 0.2 * h, look.backpack
        )
    torso_bottom = hip[1] + 0.05 * h
    canvas.polygon(
        [
            (shoulder[0] - 0.07 * h, shoulder[1] - 0.03 * h),
            (shoulder[0] + 0.06 * h, shoulder[1] - 0.03 * h),
            (shoulder[0] + 0.085 * h, shoulder[1] + 0.07 * h),
            (hip[0] + 0.08 * h, torso_bottom),
            (hip[0] - 0.08 * h, torso_bottom),
            (shoulder[0] - 0.085 * h, shoulder[1] + 0.06 * h),
        ],
        look.top,
    )
    canvas.arm(look, shoulder, h, phase + math.pi, 1.0)
    head = (shoulder[0] + 0.025 * h, shoulder[1] - 0.1 * h)
    canvas.limb([(shoulder[0] + 0.01 * h, shoulder[1] - 0.03 * h), head], 0.05 * h, look.skin)
    canvas.ellipse(head, (0.066 * h, 0.072 * h), look.skin)
    canvas.ellipse((head[0] - 0.014 * h, head[1] - 0.02 * h), (0.062 * h, 0.058 * h), look.hair)
    canvas.ellipse((head[0] + 0.022 * h, head[1] + 0.012 * h), (0.044 * h, 0.054 * h), look.skin)
    return canvas.sprite((hip_x, ground), facing_left)


@cache
def car_sprite(look: Car, length_px: int, facing_left: bool) -> Sprite:
    """A hatchback ``length_px`` long, seen from the side."""
    m = length_px * SUPERSAMPLE / look.length_m  # Supersampled pixels per metre.
    canvas = _Canvas(round((look.length_m + 0.4) * m), round((look.height_m + 0.2) * m))
    left, ground = 0.2 * m, (look.height_m + 0.1) * m

    def at(x: float, up: float) -> tuple[float, float]:
        return (left + x * m, ground - up * m)

    canvas.ellipse(at(2.1, 0.0), (2.25 * m, 0.14 * m), (0, 0, 0), SHADOW_ALPHA + 0.15)
    outline = [
        (0.0, 0.4),
        (0.02, 0.85),
        (0.35, 0.98),
        (0.95, 1.42),
        (2.55, 1.45),
        (3.25, 0.98),
        (4.1, 0.86),
        (4.2, 0.62),
        (4.2, 0.35),
        (4.05, 0.28),
        (0.12, 0.28),
    ]
    canvas.polygon([at(*p) for p in outline], look.body)
    canvas.polygon(
        [at(*p) for p in [(0.0, 0.28), (4.2, 0.28), (4.2, 0.42), (0.0, 0.42)]],
        _tint(look.body, 0.55),
    )
    glass = (70, 60, 50)
    canvas.polygon([at(*p) for p in [(0.55, 1.0), (1.05, 1.37), (1.95, 1.38), (1.95, 1.0)]], glass)
    canvas.polygon([at(*p) for p in [(2.05, 1.0), (2.05, 1.38), (2.5, 1.38), (3.08, 1.0)]], glass)
    canvas.limb([at(1.25, 1.34), at(1.7, 1.08)], 0.05 * m, (150, 140, 130))
    for x in (2.0, 3.1):
        canvas.limb([at(x, 0.95), at(x, 0.42)], 0.02 * m, _tint(look.body, 0.6))
    canvas.limb([at(1.35, 0.82), at(1.5, 0.82)], 0.04 * m, _tint(look.body, 0.6))
    canvas.limb([at(2.45, 0.82), at(2.6, 0.82)], 0.04 * m, _tint(look.body, 0.6))
    canvas.polygon(
        [at(*p) for p in [(4.0, 0.8), (4.18, 0.72), (4.18, 0.6), (4.0, 0.62)]], (190, 235, 245)
    )
    canvas.polygon(
        [at(*p) for p in [(0.01, 0.82), (0.14, 0.84), (0.14, 0.62), (0.01, 0.62)]], (40, 40, 200)
    )
    for x in (0.8, 3.4):
        canvas.ellipse(at(x, 0.33), (0.42 * m, 0.42 * m), (30, 30, 32))
        canvas.ellipse(at(x, 0.31), (0.31 * m, 0.31 * m), (28, 28, 28))
        canvas.ellipse(at(x, 0.31), (0.19 * m, 0.19 * m), (165, 165, 170))
        canvas.ellipse(at(x, 0.31), (0.06 * m, 0.06 * m), (90, 90, 95))
    return canvas.sprite(at(2.1, 0.0), facing_left)


def _leg(h: float, phase: float) -> list[tuple[float, float]]:
    """Knee, ankle and toe relative to the hip: the thigh swings, the knee bends in the
    swing (the thigh coming forward) and stays nearly straight while the foot is down."""
    thigh = math.radians(26) * math.sin(phase)
    bend = math.radians(5 + 55 * max(0.0, math.cos(phase)) ** 2)
    shin = thigh - bend
    knee = (0.245 * h * math.sin(thigh), 0.245 * h * math.cos(thigh))
    ankle = (knee[0] + 0.235 * h * math.sin(shin), knee[1] + 0.235 * h * math.cos(shin))
    toe = (ankle[0] + 0.075 * h * math.cos(shin), ankle[1] - 0.075 * h * math.sin(shin))
    return [knee, ankle, toe]


def _tint(colour: BGR, gain: float) -> BGR:
    b, g, r = (min(255, round(c * gain)) for c in colour)
    return (b, g, r)


class _Canvas:
    """Supersampled colour and coverage, drawn on with OpenCV's shapes."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self.colour = np.zeros((height, width, 3), np.float32)
        self.alpha = np.zeros((height, width), np.float32)
        self.solid = np.zeros((height, width), np.uint8)
        """What the body covers (not its shadow): what the shading rounds."""

    def _draw(self, draw: Callable[[AnyArray, Ink], object], colour: BGR, alpha: float) -> None:
        """Draw a shape in ``colour`` and ``alpha`` (1: part of the body, else a shadow)."""
        draw(self.colour, tuple(float(c) for c in colour))
        draw(self.alpha, alpha)
        if alpha == 1.0:
            draw(self.solid, 255)

    def polygon(self, points: list[tuple[float, float]], colour: BGR) -> None:
        pts = [np.round(np.array(points)).astype(np.int32)]
        self._draw(lambda canvas, value: cv2.fillPoly(canvas, pts, value), colour, 1.0)

    def limb(self, points: list[tuple[float, float]], thickness: float, colour: BGR) -> None:
        pts = [(round(x), round(y)) for x, y in points]
        width, radius = max(1, round(thickness)), max(1, round(thickness / 2))

        def draw(canvas: AnyArray, value: Ink) -> None:
            for a, b in itertools.pairwise(pts):
                cv2.line(canvas, a, b, value, width)
            for p in pts:
                cv2.circle(canvas, p, radius, value, -1)

        self._draw(draw, colour, 1.0)

    def ellipse(
        self,
        centre: tuple[float, float],
        axes: tuple[float, float],
        colour: BGR,
        alpha: float = 1.0,
    ) -> None:
        c = (round(centre[0]), round(centre[1]))
        a = (max(1, round(axes[0])), max(1, round(axes[1])))
        self._draw(
            lambda canvas, value: cv2.ellipse(canvas, c, a, 0, 0, 360, value, -1), colour, alpha
        )

    def rounded_box(self, corner: tuple[float, float], w: float, h: float, colour: BGR) -> None:
        r = 0.3 * w
        x, y = corner
        self.polygon(
            [
                (x, y + r),
                (x + r, y),
                (x + w - r, y),
                (x + w, y + r),
                (x + w, y + h - r),
                (x + w - r, y + h),
                (x + r, y + h),
                (x, y + h - r),
            ],
            colour,
        )

    def arm(
        self, look: Person, shoulder: tuple[float, float], h: float, phase: float, tint: float
    ) -> None:
        """An arm swinging against the leg of the same ``phase``."""
        upper = -math.radians(24) * math.sin(phase)
        fore = upper + math.radians(15 + 20 * max(0.0, -math.sin(phase)))
        elbow = (shoulder[0] + 0.18 * h * math.sin(upper), shoulder[1] + 0.18 * h * math.cos(upper))
        wrist = (elbow[0] + 0.15 * h * math.sin(fore), elbow[1] + 0.15 * h * math.cos(fore))
        self.limb([shoulder, elbow, wrist], 0.068 * h, _tint(look.top, tint * 0.9))
        hand = (wrist[0] + 0.03 * h * math.sin(fore), wrist[1] + 0.03 * h * math.cos(fore))
        self.ellipse(hand, (0.03 * h, 0.033 * h), _tint(look.skin, tint))

    def sprite(self, anchor: tuple[float, float], facing_left: bool) -> Sprite:
        """Shrunk, shaded, flipped if asked and cropped to what it covers."""
        small = (self.width // SUPERSAMPLE, self.height // SUPERSAMPLE)
        alpha = cv2.resize(self.alpha, small, interpolation=cv2.INTER_AREA)
        colour = cv2.resize(
            self.colour * self.alpha[..., None], small, interpolation=cv2.INTER_AREA
        )
        body = cv2.resize(self.solid, small, interpolation=cv2.INTER_AREA).astype(np.float32) / 255
        anchor_x, anchor_y = anchor[0] / SUPERSAMPLE, anchor[1] / SUPERSAMPLE
        if facing_left:
            alpha, colour, body = alpha[:, ::-1], colour[:, ::-1], body[:, ::-1]
            anchor_x = small[0] - anchor_x
        # Rounded: lighter where the outline faces the upper left, darker to the lower
        # right, as a soft light from above the camera's left shows a body.
        sigma = 0.02 * small[1]
        rim = cv2.GaussianBlur(body, (0, 0), sigma)
        relief = (cv2.Sobel(rim, cv2.CV_32F, 1, 0) + cv2.Sobel(rim, cv2.CV_32F, 0, 1)) * sigma / 8
        rows = np.arange(small[1], dtype=np.float32)[:, None] / small[1]
        light = 1.0 + 0.6 * relief - 0.12 * rows
        colour = np.clip(colour * (1.0 + (light - 1.0) * body)[..., None], 0, 255)
        faint = alpha < MIN_ALPHA
        alpha[faint] = 0.0
        colour[faint] = 0.0
        ys, xs = np.nonzero(alpha)
        y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
        return Sprite(
            np.ascontiguousarray(np.round(colour[y0:y1, x0:x1]), np.uint8),
            np.ascontiguousarray(np.round(255 * (1 - alpha[y0:y1, x0:x1, None])), np.uint8),
            (anchor_x - x0, anchor_y - y0),
        )
