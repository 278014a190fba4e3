"""Synthetic scenes with exact ground truth (known boxes and speeds).

Used by the tests and by the benchmarks (the demo camera's street, whose truth is the
same ``TruthObject``, is ``app.sources.demo_scene``). Each scene is a textured static
background, moving objects with known positions and velocities, camera noise, and
optional global events (a light switch, swaying foliage). Everything is deterministic
for a given seed.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field

import cv2
import numpy as np

from app.vision.detections import Box
from app.vision.types import Image


@dataclass(frozen=True)
class MovingObject:
    start: tuple[float, float]
    """Top-left corner (pixels) at time 0, the scene's frame 0 (shown from ``first_frame``)."""
    velocity: tuple[float, float]
    """Pixels per second."""
    size: tuple[int, int]
    intensity: int
    """Mean grey level of the object's body."""
    textured: bool = True
    first_frame: int = 0
    last_frame: int | None = None
    stop: tuple[float, float] | None = None
    """From and to (seconds of the scene): a while it stands still, then goes on."""

    def box_at(self, time_s: float) -> tuple[float, float, float, float]:
        moving_s = time_s
        if self.stop is not None:
            start, end = self.stop
            moving_s -= max(0.0, min(time_s, end) - start)
        x = self.start[0] + self.velocity[0] * moving_s
        y = self.start[1] + self.velocity[1] * moving_s
        return (x, y, float(self.size[0]), float(self.size[1]))

    @property
    def speed_px_s(self) -> float:
        return math.hypot(*self.velocity)

    def speed_at(self, time_s: float) -> float:
        stopped = self.stop is not None and self.stop[0] <= time_s < self.stop[1]
        return 0.0 if stopped else self.speed_px_s


@dataclass(frozen=True)
class TruthObject:
    object_index: int
    box: Box
    speed_px_s: float


@dataclass(frozen=True)
class Scene:
    name: str
    size: tuple[int, int] = (320, 240)
    fps: float = 15.0
    frames: int = 90
    background_mean: int = 110
    background_contrast: float = 40.0
    noise_sigma: float = 2.0
    objects: tuple[MovingObject, ...] = ()
    light_switch_frame: int | None = None
    light_gain: float = 1.7
    camera_move_frame: int | None = None
    camera_move: tuple[float, float] = (0.0, 0.0)
    """From ``camera_move_frame`` on, the camera has been knocked (dx, dy) pixels: all it
    sees, objects included, is that much the other way."""
    sway_region: tuple[int, int, int, int] | None = None
    """x, y, w, h of a patch of foliage that sways from side to side."""
    seed: int = 7
    min_visible_fraction: float = 0.5
    """A partly visible object counts as truth once this share of it is in view."""
    _cache: dict[str, np.ndarray] = field(
        default_factory=dict, init=False, compare=False, repr=False
    )
    """Rendered textures; a scene made from this one by `replace` renders its own."""

    def _background(self) -> np.ndarray:
        if "background" not in self._cache:
            rng = np.random.default_rng(self.seed)
            w, h = self.size
            coarse = rng.normal(0.0, 1.0, (max(2, h // 16), max(2, w // 16)))
            smooth = cv2.resize(coarse, (w, h), interpolation=cv2.INTER_CUBIC)
            fine = cv2.GaussianBlur(rng.normal(0.0, 1.0, (h, w)), (0, 0), 1.5)
            texture = 0.7 * smooth / (smooth.std() + 1e-9) + 0.3 * fine / (fine.std() + 1e-9)
            # A horizontal ramp makes the light switch non-uniform, as real lamps are.
            self._cache["background"] = (
                self.background_mean + self.background_contrast * 0.5 * texture
            )
            self._cache["ramp"] = np.linspace(0.8, 1.2, w)[None, :].repeat(h, axis=0)
            self._cache["foliage"] = cv2.GaussianBlur(rng.normal(0.0, 1.0, (h, w * 2)), (0, 0), 2.0)
        return self._cache["background"]

    def _object_texture(self, index: int, obj: MovingObject) -> np.ndarray:
        key = f"object{index}"
        if key not in self._cache:
            w, h = obj.size
            rng = np.random.default_rng(self.seed + 101 * (index + 1))
            if obj.textured:
                pattern = cv2.GaussianBlur(rng.normal(0.0, 1.0, (h, w)), (0, 0), 1.0)
                pattern = 12.0 * pattern / (pattern.std() + 1e-9)
            else:
                pattern = np.zeros((h, w))
            self._cache[key] = obj.intensity + pattern
        return self._cache[key]

    def frame(self, index: int) -> Image:
        """The BGR frame at ``index``."""
        time_s = index / self.fps
        image = self._background().copy()
        if self.sway_region is not None:
            x, y, w, h = self.sway_region
            shift = round(6 * math.sin(2 * math.pi * 0.8 * time_s)) + self.size[0] // 2
            foliage = self._cache["foliage"][y : y + h, shift + x : shift + x + w]
            image[y : y + h, x : x + w] += 28.0 * foliage / (foliage.std() + 1e-9)
        for i, obj in enumerate(self.objects):
            if not self._alive(obj, index):
                continue
            self._paste(image, self._object_texture(i, obj), obj.box_at(time_s))
        if self.light_switch_frame is not None and index >= self.light_switch_frame:
            image = image * self.light_gain * self._cache["ramp"] + 10.0
        if self._camera_moved(index):
            dx, dy = self.camera_move
            view = np.array([[1.0, 0.0, -dx], [0.0, 1.0, -dy]])
            image = cv2.warpAffine(image, view, self.size, borderMode=cv2.BORDER_REFLECT)
        rng = np.random.default_rng(self.seed * 1_000_003 + index)
        image = image + rng.normal(0.0, self.noise_sigma, image.shape)
        gray = np.clip(image, 0, 255).astype(np.uint8)
        return cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)

    def truth(self, index: int) -> list[TruthObject]:
        """Every object visible in frame ``index`` with its exact box and speed."""
        time_s = index / self.fps
        w, h = self.size
        out = []
        for i, obj in enumerate(self.objects):
            if not self._alive(obj, index):
                continue
            x, y, bw, bh = obj.box_at(time_s)
            if self._camera_moved(index):
                x, y = x - self.camera_move[0], y - self.camera_move[1]
            x0, y0 = max(0, math.floor(x)), max(0, math.floor(y))
            x1, y1 = min(w, math.ceil(x + bw)), min(h, math.ceil(y + bh))
            if x1 <= x0 or y1 <= y0:
                continue
            if (x1 - x0) * (y1 - y0) < self.min_visible_fraction * bw * bh:
                continue
            out.append(TruthObject(i, Box(x0, y0, x1 - x0, y1 - y0), obj.speed_at(time_s)))
        return out

    def frames_iter(self) -> Iterator[Image]:
        for index in range(self.frames):
            yield self.frame(index)

    def _camera_moved(self, index: int) -> bool:
        return self.camera_move_frame is not None and index >= self.camera_move_frame

    @staticmethod
    def _alive(obj: MovingObject, index: int) -> bool:
        return index >= obj.first_frame and (obj.last_frame is None or index <= obj.last_frame)

    @staticmethod
    def _paste(
        image: np.ndarray, texture: np.ndarray, box: tuple[float, float, float, float]
    ) -> None:
        """Draw an object at a sub-pixel position (shifted by interpolation, not rounded)."""
        x, y, w, h = box
        ix, iy = math.floor(x), math.floor(y)
        shift = np.array([[1, 0, x - ix], [0, 1, y - iy]], np.float32)
        padded_w, padded_h = int(w) + 2, int(h) + 2
        sprite = cv2.warpAffine(
            texture.astype(np.float32),
            shift,
            (padded_w, padded_h),
            flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=-1,
        )
        alpha = cv2.warpAffine(
            np.ones((int(h), int(w)), np.float32),
            shift,
            (padded_w, padded_h),
            flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=0,
        )
        ih, iw = image.shape
        sx0, sy0 = max(0, -ix), max(0, -iy)
        dx0, dy0 = max(0, ix), max(0, iy)
        dx1, dy1 = min(iw, ix + padded_w), min(ih, iy + padded_h)
        if dx1 <= dx0 or dy1 <= dy0:
            return
        region = image[dy0:dy1, dx0:dx1]
        a = alpha[sy0 : sy0 + (dy1 - dy0), sx0 : sx0 + (dx1 - dx0)]
        s = sprite[sy0 : sy0 + (dy1 - dy0), sx0 : sx0 + (dx1 - dx0)]
        region[:] = region * (1 - a) + np.maximum(s, 0) * a


def standard_scenes() -> dict[str, Scene]:
    """The scenes every method is judged on (tests/vision and bench/).

    As a watched camera sees them: an empty scene first, then objects walk
    in or step out (``first_frame``), with exact boxes and speeds.
    """
    return {
        "slow-uniform": Scene(
            name="slow-uniform",
            frames=150,
            objects=(
                MovingObject((40, 100), (6.0, 0.0), (60, 40), 200, textured=False, first_frame=15),
            ),
        ),
        # Grey 150 on a background of 110 +- 20: parts of the object match the scene behind.
        "camouflaged": Scene(
            name="camouflaged",
            frames=150,
            objects=(MovingObject((-70, 90), (30.0, 0.0), (60, 30), 150, first_frame=20),),
        ),
        # Half a pixel a frame: from one frame to the next, hardly anything changes.
        "creeping": Scene(
            name="creeping",
            frames=200,
            objects=(MovingObject((100, 80), (8.0, 0.0), (40, 60), 160, first_frame=20),),
        ),
        "small-fast": Scene(
            name="small-fast",
            frames=60,
            objects=(MovingObject((-20, 60), (120.0, 30.0), (14, 14), 220),),
        ),
        "crossing": Scene(
            name="crossing",
            frames=100,
            objects=(
                MovingObject((-10, 40), (45.0, 20.0), (24, 40), 210),
                MovingObject((306, 50), (-45.0, 18.0), (24, 40), 30),
                MovingObject((150, 236), (5.0, -26.0), (30, 30), 180),
            ),
        ),
        "night": Scene(
            name="night",
            frames=100,
            background_mean=22,
            background_contrast=10.0,
            noise_sigma=5.0,
            objects=(MovingObject((-25, 110), (30.0, 0.0), (30, 50), 50),),
        ),
        # A night camera that smooths its noise away: clean, dim, and a person only
        # eight grey levels darker than the ground.
        "dim": Scene(
            name="dim",
            frames=100,
            background_mean=28,
            background_contrast=8.0,
            noise_sigma=1.5,
            objects=(MovingObject((-25, 110), (30.0, 0.0), (30, 50), 20),),
        ),
        "dim-empty": Scene(
            name="dim-empty",
            frames=100,
            background_mean=28,
            background_contrast=8.0,
            noise_sigma=1.5,
        ),
        "light-switch": Scene(name="light-switch", frames=60, light_switch_frame=30),
        "light-switch-crossing": Scene(
            name="light-switch-crossing",
            frames=90,
            light_switch_frame=30,
            objects=(MovingObject((-20, 100), (40.0, 0.0), (28, 44), 200, first_frame=5),),
        ),
        # A dark lorry driving in until it fills most of the view: neither a light
        # switch nor noise, though most of the picture changes.
        "lorry": Scene(
            name="lorry",
            frames=90,
            min_visible_fraction=0.05,
            objects=(MovingObject((-260, 20), (60.0, 0.0), (250, 200), 30, first_frame=5),),
        ),
        # A camera knocked 5.5 pixels right and 2.5 down while someone crosses its view.
        "knocked": Scene(
            name="knocked",
            frames=90,
            camera_move_frame=45,
            camera_move=(5.5, 2.5),
            objects=(MovingObject((-20, 100), (45.0, 0.0), (28, 44), 200, first_frame=5),),
        ),
        # Someone walks in, waits four seconds (60 frames), and walks on: an object
        # that stops is still an object.
        "waiting": Scene(
            name="waiting",
            frames=150,
            objects=(
                MovingObject(
                    (-20, 100), (40.0, 0.0), (28, 44), 200, first_frame=5, stop=(3.0, 7.0)
                ),
            ),
        ),
        "swaying": Scene(
            name="swaying",
            frames=150,
            sway_region=(200, 20, 100, 120),
            objects=(MovingObject((-20, 160), (25.0, 0.0), (28, 44), 200, first_frame=30),),
        ),
        "swaying-empty": Scene(name="swaying-empty", frames=150, sway_region=(40, 30, 160, 150)),
    }


def in_view_scenes() -> dict[str, Scene]:
    """Scenes whose objects are in view at frame 0, as a recording may start: what
    offline mode's background scan is for (``app.vision.scene_background``)."""
    return {
        "box-in-view": Scene(
            name="box-in-view",
            frames=90,
            objects=(MovingObject((60, 100), (30.0, 0.0), (40, 40), 200),),
        ),
        "uniform-box-in-view": Scene(
            name="uniform-box-in-view",
            frames=90,
            objects=(MovingObject((60, 100), (20.0, 0.0), (40, 40), 200, textured=False),),
        ),
        # A dark, uniform car driving off its first-frame spot, in view to the last frame:
        # it covers the middle of its path for most of the clip.
        "dark-car-in-view": Scene(
            name="dark-car-in-view",
            frames=120,
            objects=(MovingObject((40, 120), (15.0, 0.0), (70, 35), 30, textured=False),),
        ),
        # A white box crossing a plain grey wall: its own shift explains every change,
        # as a moved view's would, yet it is the box that moves, not the camera.
        "box-on-plain-wall": Scene(
            name="box-on-plain-wall",
            frames=30,
            background_mean=60,
            background_contrast=0.0,
            objects=(MovingObject((0, 90), (60.0, 0.0), (60, 60), 220, textured=False),),
        ),
        "two-ways-in-view": Scene(
            name="two-ways-in-view",
            frames=90,
            objects=(
                MovingObject((100, 60), (25.0, 0.0), (30, 50), 190),
                MovingObject((180, 140), (-25.0, 5.0), (30, 50), 40),
            ),
        ),
        "slow-in-view": Scene(
            name="slow-in-view",
            frames=150,
            objects=(MovingObject((120, 90), (8.0, 0.0), (40, 60), 160),),
        ),
        # Dark on the textured ground and slow (0.4 px a frame): it barely stirs from
        # one frame to the next, and parts of its rim match the ground.
        "slow-dark-in-view": Scene(
            name="slow-dark-in-view",
            frames=150,
            objects=(MovingObject((60, 100), (6.0, 0.0), (30, 60), 50),),
        ),
        "fast-in-view": Scene(
            name="fast-in-view",
            frames=60,
            objects=(MovingObject((30, 30), (60.0, 40.0), (20, 20), 220),),
        ),
        "walks-away": Scene(
            name="walks-away",
            fps=25.0,
            frames=100,
            objects=(MovingObject((150, 100), (-40.0, 0.0), (28, 44), 60),),
        ),
    }
