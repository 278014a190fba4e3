"""What the scene sweep shows beyond ``app.sources.synthetic.Scene``: weather, light
that flickers, remaps or drifts, a cloud's shadow, a lamp, and a camera that pans or shakes.

An ``EffectScene`` renders a ``Scene`` (its background, objects and exact truth)
without camera noise, looks at it through a view that may move over a wider
world, changes the picture with its effects in order, then adds the scene's
camera noise (the same draws as ``Scene`` makes). A view at a fraction of a
pixel is interpolated, objects and all, as ``Scene`` does a knocked camera's:
an object's edge may then tint a pixel beyond its true box. Effects change only the
picture, never the truth: an object behind rain or in a cloud's shadow is
still an object, and rain, snow, shadows and lamps are none. Everything is
a function of the frame index and fixed seeds, so frames are the same in any
process and in any order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property
from typing import Protocol

import cv2
import numpy as np

from app.sources.synthetic import MovingObject, Scene, TruthObject
from app.vision.types import Image

FloatPicture = np.ndarray
"""A grey picture in float64, grey levels 0..255 (and beyond, before clipping)."""


class Effect(Protocol):
    def apply(self, picture: FloatPicture, index: int, fps: float) -> FloatPicture:
        """The picture of frame ``index`` with the effect: may change ``picture`` in place."""
        ...


class ViewPath(Protocol):
    margin: tuple[int, int]
    """How much wider and taller than the view the world must be."""

    def offset(self, index: int) -> tuple[float, float]:
        """Where the view's top-left corner is in the world at frame ``index``."""
        ...


class Renderable(Protocol):
    """What the sweep runs: ``Scene`` and ``EffectScene`` alike."""

    @property
    def name(self) -> str: ...
    @property
    def size(self) -> tuple[int, int]: ...
    @property
    def fps(self) -> float: ...
    @property
    def frames(self) -> int: ...
    @property
    def objects(self) -> tuple[MovingObject, ...]: ...
    def frame(self, index: int) -> Image: ...
    def truth(self, index: int) -> list[TruthObject]: ...


@dataclass(frozen=True)
class EffectScene:
    """``world`` seen through ``view`` (a window of ``view_size`` moving over it; None: the
    whole world, unmoved), with ``effects`` applied in order."""

    world: Scene
    effects: tuple[Effect, ...] = ()
    view: ViewPath | None = None

    @property
    def name(self) -> str:
        return self.world.name

    @property
    def fps(self) -> float:
        return self.world.fps

    @property
    def frames(self) -> int:
        return self.world.frames

    @property
    def objects(self) -> tuple[MovingObject, ...]:
        return self.world.objects

    @property
    def size(self) -> tuple[int, int]:
        if self.view is None:
            return self.world.size
        (w, h), (mx, my) = self.world.size, self.view.margin
        return (w - mx, h - my)

    @cached_property
    def _clean(self) -> Scene:
        return replace(self.world, noise_sigma=0.0)

    def frame(self, index: int) -> Image:
        if self.view is None and not self.effects:
            return self.world.frame(index)
        picture = self._clean.frame(index)[:, :, 0].astype(np.float64)
        if self.view is not None:
            ox, oy = self.view.offset(index)
            to_view = np.array([[1.0, 0.0, -ox], [0.0, 1.0, -oy]])
            picture = cv2.warpAffine(picture, to_view, self.size, flags=cv2.INTER_LINEAR)
        for effect in self.effects:
            picture = effect.apply(picture, index, self.fps)
        # Scene's own draws of the camera's noise.
        rng = np.random.default_rng(self.world.seed * 1_000_003 + index)
        picture = picture + rng.normal(0.0, self.world.noise_sigma, picture.shape)
        gray = np.clip(picture, 0, 255).astype(np.uint8)
        return cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)

    def truth(self, index: int) -> list[TruthObject]:
        if self.view is None:
            return self.world.truth(index)
        # A view at (ox, oy) in the world is a camera moved by (ox, oy): Scene's own truth
        # of a moved camera, in a view of this size, gives the exact visible boxes.
        window = replace(
            self.world, size=self.size, camera_move_frame=0, camera_move=self.view.offset(index)
        )
        return window.truth(index)

    def __post_init__(self) -> None:
        if self.view is not None and self.world.camera_move_frame is not None:
            raise ValueError("a moving view and a knocked camera do not combine")


def _layer(shape: tuple[int, ...]) -> np.ndarray:
    """An 8-bit drawing layer: OpenCV smooths (LINE_AA) only 8-bit pictures."""
    return np.zeros(shape, np.uint8)


def _blend(picture: FloatPicture, layer: np.ndarray, grey: float, opacity: float) -> FloatPicture:
    """``picture`` taken towards ``grey`` where ``layer`` (0..255) is drawn."""
    alpha = layer.astype(np.float64) * (opacity / 255.0)
    return picture + alpha * (grey - picture)


# --- weather ------------------------------------------------------------------------


@dataclass(frozen=True)
class Rain:
    """Streaks of ``drops`` raindrops a frame, each drawn anew: a drop falls past its own
    length from one frame to the next."""

    drops: int
    length: tuple[float, float] = (10.0, 26.0)
    slant: float = 0.2
    """Sideways pixels per pixel of fall."""
    grey: float = 200.0
    opacity: float = 0.5
    seed: int = 11

    def apply(self, picture: FloatPicture, index: int, fps: float) -> FloatPicture:
        rng = np.random.default_rng((self.seed, index))
        h, w = picture.shape
        layer = _layer(picture.shape)
        lengths = rng.uniform(*self.length, self.drops)
        xs = rng.uniform(-self.slant * lengths, w)
        ys = rng.uniform(-lengths, h)
        for x, y, length in zip(xs, ys, lengths, strict=True):
            end = (x + self.slant * length, y + length)
            cv2.line(layer, _fixed((x, y)), _fixed(end), 255, 1, cv2.LINE_AA, SHIFT)
        return _blend(picture, layer, self.grey, self.opacity)


SHIFT = 4
"""Fractional bits of the coordinates given to OpenCV's drawing (sub-pixel positions)."""


def _fixed(point: tuple[float, float]) -> tuple[int, int]:
    return (round(point[0] * 2**SHIFT), round(point[1] * 2**SHIFT))


@dataclass(frozen=True)
class Snow:
    """``flakes`` flakes that fall and drift on steady paths (each is in every frame, so a
    flake can be followed from one frame to the next), wrapping round the view; a share
    of them large and near, falling faster."""

    flakes: int
    large_share: float = 0.05
    small: tuple[float, float] = (2.0, 5.0)
    """Pixels across."""
    large: tuple[float, float] = (12.0, 20.0)
    fall: tuple[float, float] = (30.0, 70.0)
    """Pixels a second, the small flakes'; the large ones fall twice as fast."""
    grey: float = 235.0
    opacity: float = 0.85
    seed: int = 13

    def apply(self, picture: FloatPicture, index: int, fps: float) -> FloatPicture:
        rng = np.random.default_rng(self.seed)
        h, w = picture.shape
        n = self.flakes
        large = rng.random(n) < self.large_share
        across = np.where(large, rng.uniform(*self.large, n), rng.uniform(*self.small, n))
        fall = rng.uniform(*self.fall, n) * np.where(large, 2.0, 1.0)
        drift = rng.uniform(-10.0, 10.0, n)
        sway = rng.uniform(0.0, 2 * math.pi, n)
        x0, y0 = rng.uniform(0, w, n), rng.uniform(0, h, n)
        t = index / fps
        ys = (y0 + fall * t) % (h + 2 * self.large[1]) - self.large[1]
        xs = (x0 + drift * t + 4.0 * np.sin(1.5 * t + sway)) % w
        layer = _layer(picture.shape)
        for x, y, d in zip(xs, ys, across, strict=True):
            cv2.circle(layer, _fixed((x, y)), round(d / 2 * 2**SHIFT), 255, -1, cv2.LINE_AA, SHIFT)
        layer = cv2.GaussianBlur(layer, (0, 0), 0.8)  # Out of focus, near the lens.
        return _blend(picture, layer, self.grey, self.opacity)


@dataclass(frozen=True)
class CloudShadow:
    """A cloud's soft-edged shadow, ``radius`` pixels (x, y), drifting across the scene
    at ``velocity`` pixels a second from ``centre`` (the frame's pixels, at time 0): the
    light falls by ``depth`` at its middle."""

    centre: tuple[float, float]
    velocity: tuple[float, float]
    radius: tuple[float, float]
    depth: float = 0.4

    def apply(self, picture: FloatPicture, index: int, fps: float) -> FloatPicture:
        t = index / fps
        cx = self.centre[0] + self.velocity[0] * t
        cy = self.centre[1] + self.velocity[1] * t
        h, w = picture.shape
        dx = ((np.arange(w) - cx) / self.radius[0]) ** 2
        dy = ((np.arange(h) - cy) / self.radius[1]) ** 2
        # Flat in the middle, soft at the rim (a super-Gaussian): a cloud, not a lamp.
        shade = np.exp(-((dy[:, None] + dx[None, :]) ** 2))
        return picture * (1.0 - self.depth * shade)


# --- light ----------------------------------------------------------------------------


@dataclass(frozen=True)
class FlickerBands:
    """Mains light read by a rolling shutter: rows ``depth`` brighter or darker in
    ``bands`` bands a frame that drift from frame to frame, the whole view ``overall``
    with them (as in tests/vision/test_scenes.py's banded walker)."""

    depth: float = 0.25
    bands: float = 3.0
    mains_hz: float = 100.0
    overall: float = 0.1

    def apply(self, picture: FloatPicture, index: int, fps: float) -> FloatPicture:
        phase = 2 * math.pi * self.mains_hz * index / fps
        rows = np.arange(picture.shape[0])[:, None]
        bands = 1 + self.depth * np.sin(2 * math.pi * rows * self.bands / picture.shape[0] + phase)
        return picture * bands * (1 + self.overall * math.sin(phase + 0.3))


@dataclass(frozen=True)
class InfraredSwitch:
    """From ``frame`` on the camera sees by infrared: every grey level is remapped, the
    scene brighter overall and each material lighter or darker its own way (the map's
    slope runs from a quarter to 1.75 across the greys), objects too."""

    frame: int
    lift: float = 30.0
    slope: float = 1.0
    ripple: float = 12.0
    period: float = 100.0
    """Grey levels."""

    @cached_property
    def _lut(self) -> np.ndarray:
        grey = np.arange(256.0)
        return (
            self.lift + self.slope * grey + self.ripple * np.sin(2 * math.pi * grey / self.period)
        )

    def apply(self, picture: FloatPicture, index: int, fps: float) -> FloatPicture:
        if index < self.frame:
            return picture
        return self._lut[np.clip(picture, 0, 255).astype(np.uint8)]


@dataclass(frozen=True)
class Exposure:
    """The camera's gain goes from 1 to ``gain`` between frames ``start`` and ``end``
    (a step where they are equal), then stays; with ``hunt``, it also swings that much
    either way over ``period_s`` (auto-exposure hunting)."""

    start: int = 0
    end: int = 0
    gain: float = 1.0
    hunt: float = 0.0
    period_s: float = 3.0

    def apply(self, picture: FloatPicture, index: int, fps: float) -> FloatPicture:
        if index < self.start:
            ramp = 0.0
        elif index >= self.end:
            ramp = 1.0
        else:
            ramp = (index - self.start) / (self.end - self.start)
        gain = 1.0 + (self.gain - 1.0) * ramp
        gain *= 1.0 + self.hunt * math.sin(2 * math.pi * index / (fps * self.period_s))
        return picture * gain


@dataclass(frozen=True)
class Lamp:
    """A lamp comes on at ``frame``: a soft spot of light, ``brightness`` grey levels at
    ``centre`` (fractions of the width and height), a Gaussian ``spread`` pixels wide."""

    frame: int
    brightness: float
    spread: float
    centre: tuple[float, float] = (0.5, 0.5)

    def apply(self, picture: FloatPicture, index: int, fps: float) -> FloatPicture:
        if index < self.frame:
            return picture
        h, w = picture.shape
        fall_x = np.exp(-((np.arange(w) - self.centre[0] * w) ** 2) / (2 * self.spread**2))
        fall_y = np.exp(-((np.arange(h) - self.centre[1] * h) ** 2) / (2 * self.spread**2))
        return picture + self.brightness * np.outer(fall_y, fall_x)


# --- a camera that moves -------------------------------------------------------------


@dataclass(frozen=True)
class Pan:
    """The camera turns ``step`` pixels a frame (x, y) for ``frames`` frames from frame
    ``start``, and stands still before and after."""

    start: int
    frames: int
    step: tuple[float, float]

    @property
    def margin(self) -> tuple[int, int]:
        return (
            math.ceil(abs(self.step[0]) * self.frames),
            math.ceil(abs(self.step[1]) * self.frames),
        )

    def offset(self, index: int) -> tuple[float, float]:
        moved = min(max(index - self.start, 0), self.frames)
        # A turn to the left or up starts at the far side of the world.
        mx, my = self.margin
        x = moved * self.step[0] + (mx if self.step[0] < 0 else 0)
        y = moved * self.step[1] + (my if self.step[1] < 0 else 0)
        return (x, y)


@dataclass(frozen=True)
class Shake:
    """From frame ``start`` on, the view jumps each frame to a random place up to
    ``amplitude`` pixels (x and y, fractions too) from where it rests."""

    amplitude: float
    start: int = 0
    seed: int = 17

    @property
    def margin(self) -> tuple[int, int]:
        reach = 2 * math.ceil(self.amplitude)
        return (reach, reach)

    def offset(self, index: int) -> tuple[float, float]:
        rest = float(math.ceil(self.amplitude))
        if index < self.start:
            return (rest, rest)
        dx, dy = np.random.default_rng((self.seed, index)).uniform(-1, 1, 2) * self.amplitude
        return (rest + float(dx), rest + float(dy))


def seen_through(scene: Scene, view: ViewPath, *effects: Effect) -> EffectScene:
    """``scene`` as a view of its own size onto a world made wider by the view's margin
    (objects placed in the world's pixels), with ``effects``."""
    w, h = scene.size
    mx, my = view.margin
    return EffectScene(replace(scene, size=(w + mx, h + my)), effects, view)
