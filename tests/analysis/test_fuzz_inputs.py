"""Whatever a user feeds the truth and calibration parsers, they answer with a readable error."""

import json
import math
import shutil

import cv2
import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from app.analysis.calibration_file import CalibrationError, load_calibration
from app.analysis.truth import TruthError, load_truth

json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=True) | st.text(max_size=8),
    lambda children: (
        st.lists(children, max_size=5) | st.dictionaries(st.text(max_size=8), children, max_size=5)
    ),
    max_leaves=30,
)
truth_like = st.fixed_dictionaries({"frames": json_values}) | json_values
calibration_like = st.fixed_dictionaries(
    {},
    optional={
        "image_points": json_values,
        "ground_points": json_values,
        "camera_xy": json_values,
        "camera_height_m": json_values,
        "tilt_deg": json_values,
        "vertical_fov_deg": json_values,
    },
)
FUZZ = settings(
    max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


@FUZZ
@given(data=truth_like)
def test_truth_json_never_fails_unreadably(tmp_path, data):
    path = tmp_path / "truth.json"
    path.write_text(json.dumps(data))
    try:
        truth = load_truth(path)
    except TruthError as error:
        assert str(error)
    else:
        for frame in truth.frames:
            assert all(box.w > 0 and box.h > 0 for box in truth.boxes_at(frame))


@FUZZ
@given(raw=st.binary(max_size=200))
def test_truth_bytes_never_fail_unreadably(tmp_path, raw):
    path = tmp_path / "truth.json"
    path.write_bytes(raw)
    try:
        load_truth(path)
    except TruthError as error:
        assert str(error)


@FUZZ
@given(data=calibration_like)
def test_calibration_never_fails_unreadably(tmp_path, data):
    path = tmp_path / "camera.json"
    path.write_text(json.dumps(data))
    try:
        plane = load_calibration(path, (640, 480))
    except CalibrationError as error:
        assert str(error)
    else:
        plane.to_ground((320.0, 400.0))


def _png(value: int = 255, size: tuple[int, int] = (16, 12)) -> bytes:
    ok, data = cv2.imencode(".png", np.full((size[1], size[0]), value, np.uint8))
    assert ok
    return data.tobytes()


mask_files = st.dictionaries(
    st.sampled_from(
        ["gt000001.png", "gt000002.png", "gt000950.bmp", "mask.png", "in000001.jpg", "gt.png"]
    ),
    st.one_of(st.binary(max_size=64), st.builds(_png, st.integers(0, 255))),
    max_size=4,
)
temporal_rois = st.one_of(
    st.none(),
    st.binary(max_size=24),
    st.lists(st.integers(-5, 2000).map(str), max_size=3).map(lambda p: " ".join(p).encode()),
)
frame_numbers = st.one_of(st.none(), st.lists(st.one_of(st.none(), st.integers(-3, 1000))))


@FUZZ
@given(files=mask_files, temporal=temporal_rois, roi=st.binary(max_size=32), numbers=frame_numbers)
def test_cdnet_folder_never_fails_unreadably(tmp_path, files, temporal, roi, numbers):
    sequence = tmp_path / "seq"
    shutil.rmtree(sequence, ignore_errors=True)
    (sequence / "groundtruth").mkdir(parents=True)
    for name, content in files.items():
        (sequence / "groundtruth" / name).write_bytes(content)
    if temporal is not None:
        (sequence / "temporalROI.txt").write_bytes(temporal)
    if roi:
        (sequence / "ROI.bmp").write_bytes(roi)
    try:
        truth = load_truth(sequence, numbers)
        for frame in truth.frames:
            truth.boxes_at(frame)
    except TruthError as error:
        assert str(error) and "\n" not in str(error)


finite = st.floats(allow_nan=False, allow_infinity=False)
point_lists = st.lists(st.tuples(finite, finite).map(list), min_size=3, max_size=6)


@FUZZ
@given(
    image=point_lists,
    ground=point_lists,
    probe=st.tuples(st.floats(0, 640), st.floats(0, 480)),
)
def test_calibration_points_never_fail_unreadably(tmp_path, image, ground, probe):
    # Finite numbers that still break a homography: huge, equal, collinear, tiny.
    path = tmp_path / "camera.json"
    path.write_text(json.dumps({"image_points": image, "ground_points": ground}))
    try:
        plane = load_calibration(path, (640, 480))
    except CalibrationError as error:
        assert str(error)
    else:
        assert np.all(np.isfinite(plane.homography))
        where = plane.to_ground(probe)
        assert where is None or all(math.isfinite(v) for v in where)


@FUZZ
@given(
    height=finite,
    tilt=finite,
    fov=finite,
    size=st.tuples(st.integers(1, 8000), st.integers(1, 8000)),
)
def test_calibration_mounting_never_fails_unreadably(tmp_path, height, tilt, fov, size):
    path = tmp_path / "camera.json"
    path.write_text(
        json.dumps({"camera_height_m": height, "tilt_deg": tilt, "vertical_fov_deg": fov})
    )
    try:
        plane = load_calibration(path, size)
    except CalibrationError as error:
        assert str(error)
    else:
        where = plane.to_ground((size[0] / 2, size[1] - 1.0))
        assert where is None or all(math.isfinite(v) for v in where)
