"""The demo scene's still picture: a street seen from a camera on a wall across it.

The camera looks across the street, level with its length and tilted down: the ground
is a plane 5 m below it, projected with one focal length, so paving joints run to one
vanishing point and things shrink with distance as they would. From the back: shops and
houses (brick, render, windows, a bakery's awning), their pavement with a tree and a lamp,
the road (asphalt, lane markings, a manhole), the near pavement, a grass verge. Painted
once at twice the size and shrunk, so edges are smooth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from app.vision.types import AnyArray, Image

WIDTH, HEIGHT = 640, 480
PAINT_SCALE = 2


@dataclass(frozen=True)
class StreetCamera:
    """Where a point of the ground (``x_m`` along the street, ``depth_m`` from the
    camera) shows in the picture, and how many pixels a metre covers there."""

    focal_px: float = 560.0
    horizon_y: float = 60.0
    centre_x: float = WIDTH / 2
    height_m: float = 5.0

    def ground_to_image(self, x_m: float, depth_m: float) -> tuple[float, float]:
        return (
            self.centre_x + self.focal_px * x_m / depth_m,
            self.horizon_y + self.focal_px * self.height_m / depth_m,
        )

    def px_per_m(self, depth_m: float) -> float:
        return self.focal_px / depth_m


CAMERA = StreetCamera()

# Depths (metres from the camera) where the street's bands meet, back to front.
FACADE_M = 19.3
FAR_KERB_M = 15.2
ROAD_FAR_M = 14.95
CENTRE_LINE_M = 12.35
ROAD_NEAR_M = 9.75
NEAR_KERB_M = 9.5
VERGE_M = 7.3


def paint_street(seed: int = 3) -> Image:
    """The street, uint8 BGR, WIDTH x HEIGHT."""
    rng = np.random.default_rng(seed)
    s = PAINT_SCALE
    w, h = WIDTH * s, HEIGHT * s
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float32) / s
    picture = _sky(ys, rng)
    _facades(picture, xs, ys, rng)
    _ground(picture, rng)
    _tree_shadow(picture)
    _lamp(picture, x_m=-4.0, depth_m=FACADE_M - 0.5)
    _tree(picture, x_m=3.4, depth_m=FACADE_M - 0.7, rng=rng)
    picture = cv2.resize(picture, (WIDTH, HEIGHT), interpolation=cv2.INTER_AREA)
    # A lens darker at the corners, and a fine grain over all (the same in every frame).
    grain = cv2.GaussianBlur(rng.normal(0, 3.0, (HEIGHT, WIDTH)).astype(np.float32), (0, 0), 0.6)
    yy, xx = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float32)
    vignette = 1.0 - 0.22 * (((xx - WIDTH / 2) / WIDTH) ** 2 + ((yy - HEIGHT / 2) / HEIGHT) ** 2)
    picture = picture * vignette[..., None] + grain[..., None]
    return np.clip(picture, 0, 255).astype(np.uint8)


def _sky(ys: AnyArray, rng: np.random.Generator) -> AnyArray:
    h, w = ys.shape
    t = np.clip(ys / (CAMERA.horizon_y * 1.6), 0, 1)[..., None]
    top, low = np.array([215, 165, 110], np.float32), np.array([240, 220, 200], np.float32)
    sky = top * (1 - t) + low * t
    clouds = cv2.resize(
        rng.normal(0, 1, (6, 24)).astype(np.float32), (w, h), interpolation=cv2.INTER_CUBIC
    )
    return sky + 30 * np.clip(clouds - 0.4, 0, None)[..., None]


@dataclass(frozen=True)
class _Building:
    left: float
    right: float
    roof_y: float
    wall: tuple[int, int, int]
    brick: bool
    window_frame: tuple[int, int, int]


BUILDINGS = (
    _Building(-1, 205, 22, (60, 75, 150), True, (235, 235, 235)),
    _Building(205, 430, -1, (175, 205, 220), False, (70, 70, 60)),
    _Building(430, 641, 36, (120, 160, 185), True, (245, 245, 245)),
)
STOREY_M = 3.0


def _facades(picture: AnyArray, xs: AnyArray, ys: AnyArray, rng: np.random.Generator) -> None:
    s = PAINT_SCALE
    base = CAMERA.ground_to_image(0, FACADE_M)[1]
    m = CAMERA.px_per_m(FACADE_M)
    for building in BUILDINGS:
        x0, x1 = (max(0, round(v * s)) for v in (building.left, building.right))
        y0, y1 = max(0, round(building.roof_y * s)), round(base * s) + 1
        bx, by = xs[y0:y1, x0:x1], ys[y0:y1, x0:x1]
        tone = np.array(building.wall, np.float32)
        if building.brick:
            row = np.floor(by / (0.075 * m))
            shifted = bx + (row % 2) * 0.11 * m
            col = np.floor(shifted / (0.22 * m))
            shade = 1 + 0.12 * np.sin(row * 12.9898 + col * 78.233) * np.cos(col * 3.1 + row)
            mortar = ((by % (0.075 * m)) < 0.5) | ((shifted % (0.22 * m)) < 0.5)
            wall = np.where(mortar[..., None], np.float32(175), tone * shade[..., None])
        else:
            fade = 1 - 0.05 * (by - building.roof_y) / (base - building.roof_y)
            wall = tone * fade[..., None]
        picture[y0:y1, x0:x1] = wall
        if building.roof_y > 0:  # A cornice along the top.
            y = round(building.roof_y * s)
            picture[y : y + 3 * s, x0:x1] = (200, 210, 215)
            picture[y + 3 * s : y + 4 * s, x0:x1] = (110, 115, 120)
        # Upper-floor windows, then the ground floor's front.
        upper_bottom = base - STOREY_M * m
        for floor in range(3):
            sill = upper_bottom - floor * STOREY_M * m - 0.8 * m
            top = sill - 1.6 * m
            if top < building.roof_y + 4:
                break
            width = building.right - building.left
            count = max(2, round(width / (2.4 * m)))
            for k in range(count):
                cx = building.left + (k + 0.5) * width / count
                _window(picture, cx, top, sill, 1.2 * m, building.window_frame, rng)
    _shopfront(picture, 12, 180, base, m, "BAKERY", (45, 80, 30))
    _door(picture, 255, base, m, (120, 60, 30))
    _window(picture, 330, base - 2.4 * m, base - 0.9 * m, 1.5 * m, (70, 70, 60), rng)
    _window(picture, 395, base - 2.4 * m, base - 0.9 * m, 1.2 * m, (70, 70, 60), rng)
    _shopfront(picture, 445, 590, base, m, "NEWS", (90, 40, 40))
    _door(picture, 612, base, m, (40, 40, 40))
    # The walls darken where they meet the pavement.
    y0 = round((base - 0.5 * m) * s)
    y1 = round(base * s) + 1
    picture[y0:y1] *= np.linspace(1.0, 0.8, y1 - y0, dtype=np.float32)[:, None, None]


def _box(picture: AnyArray, x0: float, y0: float, x1: float, y1: float, colour: object) -> None:
    s = PAINT_SCALE
    picture[max(0, round(y0 * s)) : round(y1 * s), max(0, round(x0 * s)) : round(x1 * s)] = colour


def _glass(picture: AnyArray, x0: float, y0: float, x1: float, y1: float, warm: float) -> None:
    """Glass reflecting the sky: light above, dark below, a paler diagonal streak."""
    s = PAINT_SCALE
    r0, r1, c0, c1 = round(y0 * s), round(y1 * s), round(x0 * s), round(x1 * s)
    if r1 <= r0 or c1 <= c0:
        return
    t = np.linspace(0, 1, r1 - r0, dtype=np.float32)[:, None, None]
    upper = np.array([150, 130, 110], np.float32) + warm * np.array([-60, 0, 60], np.float32)
    lower = np.array([70, 55, 45], np.float32)
    pane = upper * (1 - t) + lower * t
    ii, jj = np.mgrid[0 : r1 - r0, 0 : c1 - c0]
    streak = np.abs((jj - ii * 0.6) / max(1, c1 - c0) - 0.35) < 0.08
    picture[r0:r1, c0:c1] = pane + 35 * streak[..., None]


def _window(
    picture: AnyArray,
    cx: float,
    top: float,
    sill: float,
    width: float,
    frame: tuple[int, int, int],
    rng: np.random.Generator,
) -> None:
    x0, x1 = cx - width / 2, cx + width / 2
    _box(picture, x0 - 1.5, top - 1.5, x1 + 1.5, sill + 1, frame)
    _glass(picture, x0 + 1, top + 1, x1 - 1, sill - 1, float(rng.uniform(-0.2, 0.6)))
    _box(picture, cx - 0.6, top, cx + 0.6, sill, frame)  # Mullion and transom.
    _box(picture, x0, top + (sill - top) * 0.35, x1, top + (sill - top) * 0.35 + 1.2, frame)
    _box(picture, x0 - 3, sill + 1, x1 + 3, sill + 3, (190, 200, 205))  # Stone sill.


def _door(
    picture: AnyArray, cx: float, base: float, m: float, colour: tuple[int, int, int]
) -> None:
    x0, x1 = cx - 0.55 * m, cx + 0.55 * m
    _box(picture, x0 - 2, base - 2.3 * m - 2, x1 + 2, base, (220, 225, 225))
    _box(picture, x0, base - 2.3 * m, x1, base, colour)
    _glass(picture, x0 + 4, base - 2.2 * m, x1 - 4, base - 1.6 * m, 0.2)
    _box(picture, x1 - 6, base - 1.1 * m, x1 - 4, base - 1.0 * m, (60, 190, 220))  # Handle.


def _shopfront(
    picture: AnyArray,
    x0: float,
    x1: float,
    base: float,
    m: float,
    name: str,
    colour: tuple[int, int, int],
) -> None:
    s = PAINT_SCALE
    top = base - 2.9 * m
    _box(picture, x0, top, x1, base, colour)
    _box(picture, x0, top, x1, top + 0.55 * m, tuple(int(c * 0.7) for c in colour))
    text_size = cv2.getTextSize(name, cv2.FONT_HERSHEY_DUPLEX, 1.0, 2)[0]
    scale = min(0.4 * m * s / text_size[1], 0.8 * (x1 - x0) * s / text_size[0])
    tw, th = (round(v * scale) for v in text_size)
    org = (round((x0 + x1) / 2 * s - tw / 2), round((top + 0.275 * m) * s + th / 2))
    sign = picture[round(top * s) : round((top + 0.55 * m) * s), round(x0 * s) : round(x1 * s)]
    letters = np.zeros(sign.shape[:2], np.uint8)
    org = (org[0] - round(x0 * s), org[1] - round(top * s))
    cv2.putText(
        letters,
        name,
        org,
        cv2.FONT_HERSHEY_DUPLEX,
        scale,
        255,
        max(1, round(2 * scale)),
        cv2.LINE_AA,
    )
    ink = (letters.astype(np.float32) / 255)[..., None]
    sign[:] = sign * (1 - ink) + np.array([215, 235, 245], np.float32) * ink
    _glass(picture, x0 + 4, top + 0.7 * m, x1 - 4, base - 0.45 * m, 0.5)
    for k in range(1, 3):  # Glazing bars.
        x = x0 + k * (x1 - x0) / 3
        _box(picture, x - 1, top + 0.7 * m, x + 1, base - 0.45 * m, colour)
    # An awning, striped, leaning out over the window.
    awning = (
        np.array(
            [
                (x0 - 4, top + 0.55 * m),
                (x1 + 4, top + 0.55 * m),
                (x1 + 10, top + 1.2 * m),
                (x0 - 10, top + 1.2 * m),
            ]
        )
        * s
    )
    awning[:, 0] = np.clip(awning[:, 0], 0, picture.shape[1] - 1)
    left, upper = np.floor(awning.min(axis=0)).astype(int)
    region = picture[upper : round(awning[:, 1].max()) + 1, left : round(awning[:, 0].max()) + 1]
    stripes = np.zeros(region.shape[:2], np.uint8)
    cv2.fillPoly(stripes, [np.round(awning - (left, upper)).astype(np.int32)], 255)
    ys, xs = np.nonzero(stripes)
    light = (((xs + left) / s - x0) // 7) % 2 == 0
    fold = 0.82 + 0.18 * ys / max(1, ys.max())
    region[ys, xs] = np.where(light[:, None], (225, 235, 240), colour) * fold[:, None]


def _ground(picture: AnyArray, rng: np.random.Generator) -> None:
    """Paint the ground, band by band from the facades to the bottom of the picture: each
    band is rows of the picture, as each row of the ground is one depth."""
    s = PAINT_SCALE
    bands = (
        (FACADE_M, FAR_KERB_M, _far_pavement),
        (FAR_KERB_M, ROAD_FAR_M, _kerb),
        (ROAD_FAR_M, ROAD_NEAR_M, _road),
        (ROAD_NEAR_M, NEAR_KERB_M, _kerb),
        (NEAR_KERB_M, VERGE_M, _near_pavement),
        (VERGE_M, 0.0, _verge),
    )
    for far, near, paint in bands:
        r0 = math.ceil(CAMERA.ground_to_image(0, far)[1] * s)
        r1 = picture.shape[0] if near == 0 else math.ceil(CAMERA.ground_to_image(0, near)[1] * s)
        y = (np.arange(r0, r1, dtype=np.float32)[:, None] + 0.5) / s
        x = (np.arange(picture.shape[1], dtype=np.float32)[None, :] + 0.5) / s
        depth = CAMERA.focal_px * CAMERA.height_m / (y - CAMERA.horizon_y) + 0 * x
        along = (x - CAMERA.centre_x) * depth / CAMERA.focal_px
        ground = _Ground(
            along,
            depth,
            rng.normal(0, 1, depth.shape).astype(np.float32),
            1.2 * depth / (CAMERA.focal_px * s),
            far,
            near,
        )
        picture[r0:r1] = paint(ground)


@dataclass(frozen=True)
class _Ground:
    """A band of ground: per pixel, metres along the street and from the camera."""

    along: AnyArray
    depth: AnyArray
    noise: AnyArray
    joint_m: AnyArray
    """A line about a pixel wide, wherever it is."""
    far: float
    near: float

    def slabs(self, size: float, base: tuple[int, int, int], spread: float) -> AnyArray:
        i, j = np.floor(self.along / size), np.floor(self.depth / size)
        tone = 1 + spread * np.sin(i * 91.7 + j * 47.3) * np.sin(i * 13.1 - j * 7.9)
        a, d = self.along % size, self.depth % size
        seam = (np.minimum(a, size - a) < self.joint_m) | (np.minimum(d, size - d) < self.joint_m)
        out = np.array(base, np.float32) * (tone + 0.025 * self.noise)[..., None]
        out[seam] *= 0.72
        return out


def _far_pavement(g: _Ground) -> AnyArray:
    return g.slabs(0.6, (165, 172, 178), 0.05)


def _near_pavement(g: _Ground) -> AnyArray:
    return g.slabs(0.45, (150, 160, 168), 0.06)


def _kerb(g: _Ground) -> AnyArray:
    """Granite kerb stones a metre long, their face darker toward the road."""
    toward_road = np.abs(g.depth - g.far) / abs(g.near - g.far)
    stone = (
        np.array([178, 182, 184], np.float32) * (1 - 0.25 * toward_road + 0.03 * g.noise)[..., None]
    )
    stone[np.abs(g.along % 1.0) < g.joint_m] *= 0.7
    return stone


def _road(g: _Ground) -> AnyArray:
    """Asphalt, darker by the kerbs, a dashed centre line, double yellow lines on the far
    side, a manhole."""
    along, depth = g.along, g.depth
    patch = np.sin(along * 0.9 + depth * 1.7) * np.sin(along * 0.37 - depth * 2.3)
    gutter = np.clip(1 - np.minimum(ROAD_FAR_M - depth, depth - ROAD_NEAR_M) / 0.4, 0, 1)
    asphalt = (
        np.array([72, 72, 74], np.float32)
        * (1 + 0.12 * g.noise + 0.06 * patch - 0.25 * gutter)[..., None]
    )
    centre = (np.abs(depth - CENTRE_LINE_M) < 0.07) & ((along % 6.0) < 3.0)
    yellow = (np.abs(depth - (ROAD_FAR_M - 0.25)) < 0.05) | (
        np.abs(depth - (ROAD_FAR_M - 0.4)) < 0.05
    )
    asphalt[centre] = (215, 225, 228)
    asphalt[yellow] = (40, 190, 225)
    manhole = np.hypot(along + 4.0, depth - 11.2) < 0.4
    asphalt[manhole] = np.where(np.sin(along[manhole] * 40)[:, None] > 0, 70, 55)
    return asphalt


def _verge(g: _Ground) -> AnyArray:
    blades = np.sin(g.along * 173.0 + g.noise * 2) * np.sin(g.along * 67.0 - g.depth * 31.0)
    edge = np.clip((VERGE_M - g.depth) / 0.6, 0, 1)
    return (
        np.array([55, 125, 75], np.float32)
        * (1 + 0.18 * blades + 0.08 * g.noise - 0.2 * edge)[..., None]
    )


def _tree_shadow(picture: AnyArray) -> None:
    """The tree's canopy shades the pavement and the road beyond its trunk."""
    s = PAINT_SCALE
    spot = np.zeros(picture.shape[:2], np.float32)
    x, y = CAMERA.ground_to_image(4.0, FAR_KERB_M + 1.5)
    cv2.ellipse(spot, (round(x * s), round(y * s)), (60 * s, 11 * s), 0, 0, 360, 1.0, -1)
    shade = cv2.GaussianBlur(spot, (0, 0), 6 * s)
    base = CAMERA.ground_to_image(0, FACADE_M)[1]
    shade[: round(base * s)] = 0
    picture *= (1 - 0.3 * shade)[..., None]


def _lamp(picture: AnyArray, x_m: float, depth_m: float) -> None:
    s = PAINT_SCALE
    m = CAMERA.px_per_m(depth_m)
    x, y = CAMERA.ground_to_image(x_m, depth_m)
    top = y - 4.8 * m
    post = (50, 55, 45)
    _box(picture, x - 0.09 * m, top, x + 0.09 * m, y, post)
    _box(picture, x - 0.16 * m, y - 0.6 * m, x + 0.16 * m, y, post)
    head = (
        np.array(
            [
                (x - 0.3 * m, top - 0.7 * m),
                (x + 0.3 * m, top - 0.7 * m),
                (x + 0.18 * m, top),
                (x - 0.18 * m, top),
            ]
        )
        * s
    )
    cv2.fillPoly(picture, [np.round(head).astype(np.int32)], (150, 225, 240))
    cv2.polylines(picture, [np.round(head).astype(np.int32)], True, post, 2 * s)
    _box(picture, x - 0.35 * m, top - 0.85 * m, x + 0.35 * m, top - 0.7 * m, post)


def _tree(picture: AnyArray, x_m: float, depth_m: float, rng: np.random.Generator) -> None:
    s = PAINT_SCALE
    m = CAMERA.px_per_m(depth_m)
    x, y = CAMERA.ground_to_image(x_m, depth_m)
    h, w = picture.shape[:2]
    trunk = np.zeros((h, w), np.uint8)
    pts = (
        np.array(
            [
                (x - 0.2 * m, y),
                (x + 0.2 * m, y),
                (x + 0.12 * m, y - 3.2 * m),
                (x - 0.12 * m, y - 3.2 * m),
            ]
        )
        * s
    )
    cv2.fillPoly(trunk, [np.round(pts).astype(np.int32)], 255)
    ty, tx = np.nonzero(trunk)
    bark = 0.65 + 0.5 * np.clip((x * s - tx) / (0.2 * m * s), -1, 1) * 0.5
    picture[ty, tx] = np.array([45, 65, 85], np.float32) * bark[:, None]
    # The canopy: overlapping clumps of leaves, ragged at the rim, lit from the upper left,
    # painted within its reach (the top of the picture cuts it).
    centre = (x * s, (y - 5.2 * m) * s)
    reach = 3.2 * m * s
    left, top = max(0, round(centre[0] - reach)), max(0, round(centre[1] - reach))
    right, bottom = min(w, round(centre[0] + reach)), min(h, round(centre[1] + reach))
    region = picture[top:bottom, left:right]
    field = np.zeros(region.shape[:2], np.float32)
    for _ in range(22):
        angle, spread = rng.uniform(0, 2 * math.pi), rng.uniform(0, 1.6 * m * s)
        cx = centre[0] - left + spread * math.cos(angle) * 1.2
        cy = centre[1] - top + spread * math.sin(angle)
        cv2.circle(field, (round(cx), round(cy)), round(rng.uniform(0.9, 1.4) * m * s), 1.0, -1)
    speckle = rng.normal(0, 1, field.shape).astype(np.float32)
    leaves = cv2.GaussianBlur(speckle, (0, 0), 1.2 * s)
    leaves = leaves / leaves.std()
    soft = cv2.GaussianBlur(field, (0, 0), 0.5 * m * s)
    cy_idx, cx_idx = np.nonzero(soft + 0.12 * leaves > 0.55)
    light = 1.15 - 0.5 * ((cy_idx + top - centre[1]) + 0.6 * (cx_idx + left - centre[0])) / (
        3 * m * s
    )
    tone = np.clip(light + 0.25 * leaves[cy_idx, cx_idx], 0.35, 1.5)
    region[cy_idx, cx_idx] = np.array([50, 120, 70], np.float32) * tone[:, None]
