import json

import cv2
import numpy as np
import pytest

from app.analysis.truth import TruthError, load_truth


def write_label(path, boxes, size=(64, 48)):
    label = np.zeros((size[1], size[0]), np.uint8)
    for x, y, w, h in boxes:
        label[y : y + h, x : x + w] = 255
    cv2.imwrite(str(path), label)


def test_cdnet_folder_matches_frames_by_number_and_honours_temporal_roi(tmp_path):
    seq = tmp_path / "seq"
    (seq / "groundtruth").mkdir(parents=True)
    for n in range(100, 106):
        write_label(seq / "groundtruth" / f"gt{n:06d}.png", [(n - 100, 5, 10, 10)])
    (seq / "temporalROI.txt").write_text("101 104\n")
    cv2.imwrite(str(seq / "ROI.bmp"), np.full((48, 64), 255, np.uint8))
    # The input is frames in000102.jpg .. in000105.jpg: frame 0 is number 102.
    truth = load_truth(seq, [102, 103, 104, 105])
    assert truth.frames == [0, 1, 2]  # 105 lies outside the temporal ROI
    assert truth.boxes_at(0)[0].as_list() == [2, 5, 10, 10]
    assert truth.roi is not None
    assert load_truth(seq / "groundtruth", [102, 103, 104, 105]).frames == [0, 1, 2]


def test_cdnet_folder_for_a_video_matches_by_order(tmp_path):
    (tmp_path / "groundtruth").mkdir()
    for n in (950, 951, 952):
        write_label(tmp_path / "groundtruth" / f"gt{n:06d}.png", [(1, 1, 5, 5)])
    assert load_truth(tmp_path, None).frames == [0, 1, 2]


def test_single_mask_named_by_frame_number(tmp_path):
    path = tmp_path / "hand_segmented_00247.png"
    write_label(path, [(10, 10, 20, 20)])
    truth = load_truth(path, None)
    assert truth.frames == [247]
    assert truth.mask(247)[15, 15] == 255


@pytest.mark.parametrize(
    "data",
    [
        {"frames": {"0": [[1, 2, 3, 4]], "2": []}},
        {
            "frames": [
                {"frame": 0, "boxes": [{"x": 1, "y": 2, "w": 3, "h": 4}]},
                {"frame": 2, "boxes": []},
            ]
        },
    ],
)
def test_box_json_in_both_documented_shapes(tmp_path, data):
    path = tmp_path / "t.json"
    path.write_text(json.dumps(data))
    truth = load_truth(path)
    assert truth.frames == [0, 2]
    assert truth.boxes_at(0)[0].as_list() == [1, 2, 3, 4]
    assert truth.boxes_at(2) == []


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("not json", "cannot read"),
        ('{"boxes": []}', "frames"),
        ('{"frames": {"x": []}}', "not a frame number"),
        ('{"frames": {"0": [[1, 2, 0, 4]]}}', "no area"),
        ('{"frames": {"0": [["a", 2, 3, 4]]}}', "a box is"),
        ('{"frames": {"-1": [[0, 0, 5, 5]]}}', "below 0"),
        ('{"frames": {"0": "0, 0, 5, 5"}}', "needs a list of boxes"),
    ],
)
def test_bad_box_json_gives_a_readable_error(tmp_path, content, message):
    path = tmp_path / "t.json"
    path.write_text(content)
    with pytest.raises(TruthError, match=message):
        load_truth(path)


def test_missing_or_unknown_truth(tmp_path):
    with pytest.raises(TruthError, match="not found"):
        load_truth(tmp_path / "nope.json")
    (tmp_path / "t.txt").write_text("x")
    with pytest.raises(TruthError, match="unknown"):
        load_truth(tmp_path / "t.txt")
    (tmp_path / "empty").mkdir()
    with pytest.raises(TruthError, match="no ground-truth images"):
        load_truth(tmp_path / "empty")
