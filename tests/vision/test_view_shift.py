"""Whether a shift of the view explains how a picture differs from the scene."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from app.vision.view_shift import shift_explains, shifted

SIZE = (120, 160)
THRESHOLD = 12.0


def detailed_scene(seed: int, contrast: float = 40.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    texture = cv2.GaussianBlur(rng.normal(0.0, 1.0, SIZE), (0, 0), 1.5)
    return np.clip(110 + contrast * texture / texture.std(), 0, 255).astype(np.float32)


def moved_view(scene: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """``scene`` as a camera moved (-dx, -dy) pixels sees it: its content moved (dx, dy)."""
    return shifted(scene, dx, dy, scene.copy())


@pytest.mark.parametrize("move", [(2.0, 0.0), (0.0, -1.5), (3.0, 1.0)])
def test_a_view_that_moved_is_explained_by_its_shift(move):
    scene = detailed_scene(1)
    picture = moved_view(scene, *move)
    assert shift_explains(scene, picture, *move, THRESHOLD)
    assert not shift_explains(scene, picture, -move[0], -move[1], THRESHOLD)


def test_an_object_in_a_moved_view_leaves_it_explained():
    scene = detailed_scene(2)
    picture = moved_view(scene, 2.0, 0.0)
    picture[40:70, 60:80] = 250.0  # Someone in view, a fifth of the change at most.
    assert shift_explains(scene, picture, 2.0, 0.0, THRESHOLD)


def test_leaves_that_sway_by_a_shift_of_their_own_are_no_moved_view():
    # Half the view, leaves, sways two pixels sideways; the rest, of fainter detail,
    # stays put. The shift explains nearly all that changed: only where the still scene
    # does not follow it does it show that the view did not move.
    scene = detailed_scene(3, contrast=10.0)
    leaves = (slice(0, 120), slice(0, 80))
    scene[leaves] = detailed_scene(5)[leaves]
    picture = scene.copy()
    picture[leaves] = moved_view(scene, 2.0, 0.0)[leaves]
    assert not shift_explains(scene, picture, 2.0, 0.0, THRESHOLD)


def test_a_shift_that_changes_nothing_where_the_picture_is_plain_still_counts():
    # Detail on the left half only: the plain right half cannot show the move either way.
    scene = detailed_scene(4)
    scene[:, 80:] = 120.0
    picture = moved_view(scene, 0.0, 2.0)
    assert shift_explains(scene, picture, 0.0, 2.0, THRESHOLD)


def test_a_time_stamp_that_stays_put_over_plain_sky_leaves_a_moved_view_explained():
    # The sky's part of the view has no detail but the stamp, which does not move.
    scene = detailed_scene(6)
    scene[:30, :] = 170.0
    stamp = (slice(4, 16), slice(4, 36))
    scene[stamp] = np.where(detailed_scene(7)[stamp] > 110, 250.0, 20.0)
    picture = moved_view(scene, 2.0, 0.0)
    picture[stamp] = scene[stamp]
    assert shift_explains(scene, picture, 2.0, 0.0, THRESHOLD)


def test_a_box_that_moved_across_a_plain_wall_is_no_moved_view():
    # All the detail is the box's: its own shift explains every change, as a moved
    # view's would, but what moved is the box, and that is motion to report.
    scene = np.full(SIZE, 60.0, np.float32)
    scene[40:70, 50:80] = 220.0
    picture = np.full(SIZE, 60.0, np.float32)
    picture[40:70, 53:83] = 220.0
    assert not shift_explains(scene, picture, 3.0, 0.0, THRESHOLD)


def test_a_knock_under_a_plain_sky_is_a_moved_view():
    # Ground below a plain sky that fills 60% of the view: the detail is in fewer rows of
    # the view than not, but in half of its parts.
    scene = detailed_scene(8)
    scene[:72] = 170.0
    picture = moved_view(scene, 3.0, 1.0)
    assert shift_explains(scene, picture, 3.0, 1.0, THRESHOLD)


def test_a_time_stamp_and_one_object_are_no_pan():
    # A plain yard with a stamp in a corner and one textured car that moved: the car's
    # shift explains the change, and the stamp reaches across the view, but stays put.
    scene = np.full(SIZE, 100.0, np.float32)
    stamp = (slice(4, 16), slice(4, 36))
    scene[stamp] = np.where(detailed_scene(7)[stamp] > 110, 250.0, 20.0)
    car = detailed_scene(9)[60:110, 90:150]
    scene[60:110, 80:140] = car
    picture = scene.copy()
    picture[60:110, 80:140] = 100.0
    picture[60:110, 94:154] = car
    assert not shift_explains(scene, picture, 14.0, 0.0, THRESHOLD, pan=True)
    assert not shift_explains(scene, picture, 14.0, 0.0, THRESHOLD)


def test_a_pan_over_signs_on_plain_walls_is_a_moved_view():
    # Signs spread over the view, but in fewer than half of its parts: too little detail to
    # tell a knock from one object's move, enough to tell a pan.
    wall = np.full((120, 240), 110.0, np.float32)
    for x, y in ((20, 15), (70, 40), (120, 80), (160, 20), (200, 95), (100, 100)):
        wall[y : y + 12, x : x + 10] = 200.0
    scene, panned = wall[:, :160], wall[:, 32:192]
    assert shift_explains(scene, panned, -32.0, 0.0, THRESHOLD, pan=True)
    assert not shift_explains(scene, panned, -32.0, 0.0, THRESHOLD)
