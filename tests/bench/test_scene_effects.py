"""What the scene sweep shows beyond Scene (bench/scene_effects.py): each effect renders the
same frames every time and leaves the truth as it was, and a view that pans or shakes keeps
each object's true box round the object."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from app.sources.synthetic import MovingObject, Scene

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

import scene_effects as fx

SMALL = Scene(
    "small",
    size=(160, 120),
    frames=12,
    objects=(MovingObject((-10, 40), (60.0, 0.0), (20, 30), 200, first_frame=2),),
)
EFFECTS: dict[str, fx.Effect] = {
    "rain": fx.Rain(drops=30),
    "snow": fx.Snow(flakes=40, large_share=0.2),
    "bands": fx.FlickerBands(),
    "infrared": fx.InfraredSwitch(frame=3),
    "cloud": fx.CloudShadow((40, 60), (30.0, 0.0), (50, 40)),
    "exposure": fx.Exposure(start=2, end=6, gain=1.3, hunt=0.1),
    "lamp": fx.Lamp(frame=3, brightness=60, spread=10),
}


@pytest.mark.parametrize("name", sorted(EFFECTS))
def test_an_effect_changes_the_picture_the_same_way_every_time(name):
    scene = fx.EffectScene(SMALL, (EFFECTS[name],))
    again = fx.EffectScene(replace(SMALL), (EFFECTS[name],))  # Nothing cached shared.
    for index in (4, 9):
        frame = scene.frame(index)
        assert frame.tobytes() == again.frame(index).tobytes()
        assert frame.shape == (120, 160, 3)
        assert np.abs(frame.astype(int) - SMALL.frame(index)).mean() > 0.5
        # Weather, light and lamps are no objects: the truth is the scene's.
        assert scene.truth(index) == SMALL.truth(index)


def test_a_scene_without_effects_is_the_scene_itself():
    plain = fx.EffectScene(SMALL)
    assert all(plain.frame(i).tobytes() == SMALL.frame(i).tobytes() for i in (0, 5))


def test_falling_snow_is_a_steady_path_and_rain_is_drawn_anew():
    # A flake can be followed from frame to frame (what makes snow hard); a raindrop cannot.
    flat = _plain("flat", frames=4, grey=40)

    def drawn(effect: fx.Effect, index: int) -> np.ndarray:
        return fx.EffectScene(flat, (effect,)).frame(index)[:, :, 0] > 70

    snow = fx.Snow(flakes=20, large_share=1.0, fall=(15.0, 15.0))
    overlap = (drawn(snow, 1) & drawn(snow, 2)).sum() / drawn(snow, 1).sum()
    rain = fx.Rain(drops=20, opacity=0.9)
    rain_overlap = (drawn(rain, 1) & drawn(rain, 2)).sum() / drawn(rain, 1).sum()
    assert overlap > 0.5 > 0.2 > rain_overlap


@pytest.mark.parametrize(
    "view", [fx.Pan(start=1, frames=6, step=(2.25, -1.5)), fx.Shake(amplitude=2.5)]
)
def test_a_moving_view_keeps_the_truth_box_round_the_object_to_the_pixel(view):
    # A plain, noiseless world: the pixels that differ from the ground are the object's.
    # Those it covers at least half of lie inside the truth; those it tints at all span
    # it, and at most a pixel more (a view at a fraction of a pixel is interpolated).
    box = MovingObject((30.5, 40.25), (30.0, 15.0), (24, 30), 250, textured=False)
    world = _plain("view", frames=8, grey=50, objects=(box,))
    scene = fx.seen_through(world, view)
    assert scene.size == world.size
    for index in range(scene.frames):
        difference = scene.frame(index)[:, :, 0].astype(int) - 50
        (truth,) = scene.truth(index)
        t = truth.box
        inside = _bounds(difference >= 100)
        tinted = _bounds(difference > 0)
        assert t.x <= inside[0] and t.y <= inside[1], index
        assert inside[2] <= t.x + t.w and inside[3] <= t.y + t.h, index
        assert tinted[0] <= t.x and tinted[1] <= t.y, index
        assert t.x + t.w <= tinted[2] and t.y + t.h <= tinted[3], index
        assert tinted[0] >= t.x - 1 and tinted[1] >= t.y - 1, index
        assert tinted[2] <= t.x + t.w + 1 and tinted[3] <= t.y + t.h + 1, index
    assert len({view.offset(index) for index in range(scene.frames)}) > 4


def _plain(name: str, frames: int, grey: int, objects: tuple[MovingObject, ...] = ()) -> Scene:
    """A plain, noiseless ground of ``grey``, 160x120."""
    return Scene(
        name,
        size=(160, 120),
        frames=frames,
        background_mean=grey,
        background_contrast=0.0,
        noise_sigma=0.0,
        objects=objects,
    )


def _bounds(mask: np.ndarray) -> tuple[int, int, int, int]:
    ys, xs = np.nonzero(mask)
    return (int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1)
