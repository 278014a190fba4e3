"""Whatever a user feeds the truth and calibration parsers, they answer with a readable error."""

import json

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
