"""The /ws messages' models: their wire form is the JSON the page and clients read, and
docs/websocket.md shows their JSON Schema as the models give it."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from types import ModuleType

import pytest
from pydantic import ValidationError

from app.events.messages import (
    MESSAGES,
    Alarm,
    AnalysisStatus,
    CameraStatus,
    Progress,
    SnapshotsDeleted,
    message_schemas,
    parse_message,
)
from app.vision.detections import Box, Detection
from app.workers.camera import STATUS_FIELDS, _alarm_object, motion_end_message, status_fields

ROOT = Path(__file__).resolve().parents[2]


def _round_trips(wire: dict) -> type:
    """The model ``wire`` parses as, after checking it gives back exactly ``wire``."""
    message = parse_message(wire)
    assert message.wire() == wire
    assert json.loads(json.dumps(message.wire())) == wire
    return type(message)


def test_motion_end_and_alarm_objects_keep_their_keys_and_rounding() -> None:
    assert motion_end_message(3, 7, 1700000000.25, 2.34567, 1234.56).wire() == {
        "type": "motion_end",
        "camera_id": 3,
        "event_id": 7,
        "ts": 1700000000.25,
        "duration_s": 2.346,
        "max_area": 1234.6,
        "clip": None,
        "clip_s": None,
    }
    clipped = motion_end_message(3, 7, 1.0, 2.0, 3.0, "/api/events/7/clip.mp4", 7.12345)
    assert clipped.wire()["clip"] == "/api/events/7/clip.mp4"
    assert clipped.wire()["clip_s"] == 7.123
    assert motion_end_message(3, 7, 1.0, 2.0, 3.0, node="north").wire()["node"] == "north"
    tracked = Detection(Box(1, 2, 30, 40), (16.0, 22.0), 1200, 0, 5, 3.14159, 47.123)
    assert _alarm_object(tracked).model_dump() == {
        "track_id": 5,
        "box": [1, 2, 30, 40],
        "area": 1200,  # A whole number stays one: the JSON says 1200, not 1200.0.
        "speed_px_s": 47.12,
        "distance_px": 3.14,
    }


def test_a_cameras_status_has_the_apis_fields_and_status_means_camera_or_analysis() -> None:
    camera = CameraStatus(**status_fields(4, fps=12.3456, motion=0.123456)).wire()
    assert list(camera) == ["type", *STATUS_FIELDS]
    assert camera["type"] == "status" and camera["fps"] == 12.35 and camera["motion"] == 0.12346
    assert _round_trips(camera) is CameraStatus
    assert _round_trips({**camera, "storage_error": None, "process": 1}) is CameraStatus
    queued = AnalysisStatus(analysis_id="ab12", status="queued").wire()
    assert queued == {"type": "status", "analysis_id": "ab12", "status": "queued"}
    assert _round_trips(queued) is AnalysisStatus
    done = {**queued, "status": "done", "error": None, "warnings": ["frame 3 skipped"]}
    assert _round_trips(done) is AnalysisStatus


def test_optional_keys_go_out_only_when_the_sender_set_them() -> None:
    assert Progress(analysis_id="a", progress=0.0).wire() == {
        "type": "progress",
        "analysis_id": "a",
        "progress": 0.0,
    }
    assert Progress(analysis_id="a", progress=0.5, frames=None).wire()["frames"] is None
    failed = AnalysisStatus(analysis_id="a", status="failed", error="not a video")
    assert "warnings" not in failed.wire()


@pytest.mark.parametrize(
    "wire",
    [
        {"type": "status", "camera_id": 1},  # A camera's status without its state.
        {"type": "snapshots_deleted", "ids": []},
        {"type": "snapshots_deleted", "ids": [1], "extra": 2},  # No unknown key.
        {"type": "snapshots_deleted", "ids": ["1"]},  # Strict: no coercion.
        {"type": "progress", "analysis_id": "a", "progress": 1.5},
        {"type": "status", "analysis_id": "a", "status": "paused"},
        {"type": "beep"},
    ],
)
def test_what_is_no_message_is_refused(wire: dict) -> None:
    with pytest.raises(ValidationError):
        parse_message(wire)


def test_a_sender_cannot_make_a_message_of_the_wrong_shape() -> None:
    with pytest.raises(ValidationError):
        SnapshotsDeleted(ids=list(range(1001)))
    with pytest.raises(ValidationError):
        Alarm.model_validate({"type": "alarm", "camera_id": 1})


# --- docs/websocket.md --------------------------------------------------------------------


def _schema_tool() -> ModuleType:
    spec = importlib.util.spec_from_file_location("update_schemas", ROOT / "docs/update_schemas.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_docs_show_each_models_json_schema() -> None:
    """Regenerate with ``python docs/update_schemas.py`` after changing a model."""
    tool = _schema_tool()
    text = (ROOT / "docs/websocket.md").read_text()
    assert tool.updated(text) == text, "docs/websocket.md is stale: run docs/update_schemas.py"
    assert set(tool.blocks(text)) == {model.__name__ for model in MESSAGES}
    for name, block in tool.blocks(text).items():
        assert json.loads(block) == message_schemas()[name]


def test_the_docs_examples_are_messages() -> None:
    text = (ROOT / "docs/websocket.md").read_text()
    examples = _schema_tool().examples(text)
    assert {type(parse_message(json.loads(e))).__name__ for e in examples} == {
        model.__name__ for model in MESSAGES
    }
