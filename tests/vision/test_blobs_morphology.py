import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from app.vision.blobs import BlobExtractor
from app.vision.detections import BOTTOM, LEFT, RIGHT, TOP
from app.vision.morphology import Morphology


def test_blobs_give_boxes_centroids_and_areas():
    mask = np.zeros((100, 100), np.uint8)
    mask[10:30, 20:60] = 255  # 40 x 20
    mask[70:80, 70:80] = 255  # 10 x 10
    detections = BlobExtractor(min_area=50)(mask)
    assert [d.box.as_list() for d in detections] == [[20, 10, 40, 20], [70, 70, 10, 10]]
    assert detections[0].area == 800
    assert detections[0].centroid == pytest.approx((39.5, 19.5), abs=0.6)


def test_min_area_drops_small_blobs():
    mask = np.zeros((50, 50), np.uint8)
    mask[5:9, 5:9] = 255  # 16 px
    mask[20:40, 20:40] = 255
    assert len(BlobExtractor(min_area=10)(mask)) == 2
    assert len(BlobExtractor(min_area=100)(mask)) == 1


def test_boxes_map_back_to_input_pixels():
    mask = np.zeros((120, 160), np.uint8)
    mask[10:20, 30:50] = 255
    (det,) = BlobExtractor(min_area=1)(mask, scale=4.0)
    assert det.box.as_list() == [120, 40, 80, 40]
    assert det.area == 200 * 16
    assert det.centroid == pytest.approx((4 * 39.5 + 1.5, 4 * 14.5 + 1.5), abs=2.5)


def test_boxes_stay_inside_a_frame_whose_reduced_copy_was_rounded():
    """480x640 (portrait) detected at 320 wide: 640 / 1.5 is 426.7 rows, rounded to 427,
    whose last row reaches input row 640.5, past the frame."""
    mask = np.zeros((427, 320), np.uint8)
    mask[400:, 300:] = 255
    (det,) = BlobExtractor(min_area=1)(mask, scale=1.5, frame_size=(480, 640))
    assert det.box.as_list() == [450, 600, 30, 40]


def test_morphology_removes_speckles_and_fills_holes():
    mask = np.zeros((60, 60), np.uint8)
    mask[10:40, 10:40] = 255
    mask[25, 25] = 0  # a hole
    mask[50, 50] = 255  # a speckle
    cleaned = Morphology(3, 5)(mask)
    assert cleaned[25, 25] == 255
    assert cleaned[50, 50] == 0


def test_blobs_name_the_frame_edges_they_touch():
    mask = np.zeros((60, 80), np.uint8)
    mask[0:10, 0:10] = 255  # the top-left corner
    mask[25:35, 70:80] = 255  # the right edge
    mask[50:60, 30:50] = 255  # the bottom edge
    mask[25:35, 30:40] = 255  # inside
    found = BlobExtractor(min_area=1)(mask, scale=2.0)  # top to bottom, left to right
    assert [d.edges for d in found] == [LEFT | TOP, 0, RIGHT, BOTTOM]


@settings(max_examples=150, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(-6, 45), st.integers(-6, 61), st.integers(1, 14), st.integers(1, 14)),
        min_size=0,
        max_size=6,
    ),
    st.sampled_from([(3, 5), (1, 5), (3, 1), (5, 7), (7, 3)]),
)
def test_morphology_of_the_motion_box_is_the_whole_frames(boxes, kernels):
    # Only the box around the motion is cleaned: the result must be OpenCV's on the
    # whole frame, blobs at the frame's edges and several far apart included.
    mask = np.zeros((40, 56), np.uint8)
    for x, y, w, h in boxes:
        mask[max(y, 0) : max(y + h, 0), max(x, 0) : max(x + w, 0)] = 255
    mask[::7, ::5] = 255 - mask[::7, ::5]  # Specks and holes.
    opening, closing = kernels
    expected = mask
    for size, operation in ((opening, cv2.MORPH_OPEN), (closing, cv2.MORPH_CLOSE)):
        if size > 1:
            ellipse = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
            expected = cv2.morphologyEx(expected, operation, ellipse)
    assert np.array_equal(Morphology(opening, closing)(mask), expected)


def test_blobs_are_found_in_the_motion_box_as_in_the_whole_frame():
    mask = np.zeros((60, 80), np.uint8)
    mask[0:5, 70:80] = 255  # A corner.
    mask[30:50, 10:30] = 255
    mask[35:45, 15:25] = 0  # A hole: the inner contour is not a blob.
    mask[38:42, 18:22] = 255  # A blob inside it, which an outer contour does not see.
    found = BlobExtractor(min_area=1)(mask)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    expected = sorted(cv2.boundingRect(c) for c in contours)
    assert sorted(tuple(d.box.as_list()) for d in found) == expected
