import numpy as np
import pytest

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
