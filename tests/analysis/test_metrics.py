import numpy as np
import pytest

from app.analysis.metrics import ObjectCounts, PixelCounts, match_boxes
from app.vision.detections import Box


def test_detection_and_false_alarm_rates_per_object_per_frame():
    counts = ObjectCounts()
    truth = [Box(0, 0, 10, 10), Box(50, 50, 10, 10)]
    counts.add(truth, [Box(1, 1, 10, 10), Box(100, 100, 5, 5)])  # 1 TP, 1 FP, 1 FN
    counts.add(truth, [Box(0, 0, 10, 10), Box(50, 50, 10, 10)])  # 2 TP
    assert (counts.tp, counts.fp, counts.fn) == (3, 1, 1)
    assert counts.detection_rate == pytest.approx(3 / 4)
    assert counts.false_alarm_rate == pytest.approx(1 / 4)


def test_one_detection_cannot_match_two_objects():
    pairs = match_boxes([Box(0, 0, 10, 10), Box(2, 0, 10, 10)], [Box(1, 0, 10, 10)])
    assert len(pairs) == 1


def test_rates_are_undefined_without_objects():
    assert ObjectCounts().detection_rate is None
    assert ObjectCounts().false_alarm_rate is None


def test_cdnet_pixel_metrics_score_only_static_and_moving_labels():
    truth = np.array([[0, 0, 255, 255, 170, 85, 50]], np.uint8)
    mask = np.array([[0, 255, 255, 0, 255, 255, 255]], np.uint8)
    counts = PixelCounts()
    counts.add(mask, truth)
    assert (counts.tp, counts.fp, counts.tn, counts.fn) == (1, 1, 1, 1)
    assert counts.recall == counts.precision == counts.f_measure == pytest.approx(0.5)
    assert counts.pwc == pytest.approx(50.0)
    assert counts.specificity == pytest.approx(0.5)


def test_roi_excludes_pixels():
    truth = np.array([[255, 0]], np.uint8)
    mask = np.array([[255, 255]], np.uint8)
    counts = PixelCounts()
    counts.add(mask, truth, roi=np.array([[255, 0]], np.uint8))
    assert (counts.tp, counts.fp) == (1, 0)
