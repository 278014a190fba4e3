import numpy as np

from app.vision.annotate import Annotator, overlay_mask
from app.vision.detections import Box, Detection


def red_pixels(image):
    b, g, r = image[..., 0].astype(int), image[..., 1].astype(int), image[..., 2].astype(int)
    return (r > 200) & (g < 60) & (b < 60)


def test_boxes_are_drawn_red_with_an_id_label_and_the_input_is_untouched():
    frame = np.full((120, 160, 3), 128, np.uint8)
    det = Detection(Box(40, 50, 30, 20), (55, 60), 600.0, track_id=7, speed_px_s=42.0)
    out = Annotator()(frame, [det], {7: [(10.0, 10.0), (30.0, 40.0), (55.0, 60.0)]})
    assert (frame == 128).all()
    assert red_pixels(out)[50, 40:70].all()  # the top edge of the box
    assert red_pixels(out)[35:50, 40:70].any()  # the label above it
    assert not red_pixels(out)[100:, :].any()
    trail = out[20:40, 15:30].astype(int)
    assert (np.abs(trail - 128).sum(axis=2) > 60).any()


def test_grey_frames_are_annotated_in_colour():
    out = Annotator()(np.zeros((50, 50), np.uint8), [Detection(Box(5, 5, 10, 10), (10, 10), 100.0)])
    assert out.shape == (50, 50, 3)


def test_calibrated_speed_is_labelled_in_km_h():
    det = Detection(Box(0, 0, 10, 10), (5, 5), 100.0, track_id=1, speed_m_s=10.0)
    assert Annotator()._label(det) == "#1 36.0 km/h"


def test_mask_overlay_tints_only_moving_pixels():
    frame = np.full((40, 40, 3), 100, np.uint8)
    mask = np.zeros((20, 20), np.uint8)
    mask[:10, :10] = 255  # detection resolution: half size
    out = overlay_mask(frame, mask)
    assert red_pixels(out).sum() == 0  # blended, not pure red
    assert out[5, 5, 2] > 150 and out[30, 30, 2] == 100
