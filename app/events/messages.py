"""The messages of ``/ws``, one pydantic model each.

Every message is a JSON object with a ``type``: ``alarm``, ``motion_end``, ``progress``,
``snapshots_deleted`` or ``status``. A ``status`` is a camera's (it has ``camera_id``) or
an analysis' (it has ``analysis_id``), as the page tells them apart: here they are two
models, ``CameraStatus`` and ``AnalysisStatus``, and ``parse_message`` tells them apart the
same way.

A sender builds the model: its fields are checked (strict types, no unknown field). What
travels is the model's ``wire()`` form, the plain dict that ``/ws`` sends as JSON. A dict
is cheap to pickle, so it is also what crosses the pipe from a camera process to the
server. Keys that only some messages of a type carry (``progress``'s ``frames``, a
status's ``storage_error``...) are left out of the wire unless the sender set them.

Nothing here knows the web: the workers and the API both import it. ``docs/websocket.md``
shows each model's JSON Schema (``message_schemas``); a test keeps the two equal.
"""

from __future__ import annotations

from typing import Annotated, Any, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Discriminator, Field, Tag, TypeAdapter
from pydantic.json_schema import GenerateJsonSchema, WithJsonSchema

Wire = dict[str, Any]
"""A message as it goes out: a dict of JSON values, ``type`` first."""

Number = Annotated[int | float, WithJsonSchema({"type": "number"})]
"""A JSON number. A whole number stays an int, so the JSON is what the sender gave."""

BoxList = Annotated[list[int], Field(min_length=4, max_length=4)]
"""``[x, y, w, h]`` in pixels of the camera's frame."""

DELETED_IDS_PER_MESSAGE = 1000
"""The most ids one ``snapshots_deleted`` message names: a large delete or prune is told
in several, each of a bounded size."""


def _type_first_and_required(schema: dict[str, Any], model: type[BaseModel]) -> None:
    """``type`` has a default for the sender's sake; to a client it is always there."""
    schema["properties"]["type"].pop("default", None)
    schema["required"] = ["type", *schema.get("required", [])]


class WsMessage(BaseModel):
    """What every message shares: strict fields, none unknown, and its ``wire()`` form."""

    model_config = ConfigDict(
        strict=True,
        extra="forbid",
        frozen=True,
        use_attribute_docstrings=True,
        json_schema_extra=_type_first_and_required,
    )

    type: str
    tag: ClassVar[str]
    """Which message this is (``status`` is two): the tag ``parse_message`` tells it by."""

    def wire(self) -> Wire:
        """The message as JSON values, ``type`` first; unset optional keys left out."""
        return {"type": self.type, **self.model_dump(exclude_unset=True)}


class AlarmObject(BaseModel):
    """One tracked object in an alarm."""

    model_config = ConfigDict(strict=True, extra="forbid", frozen=True)

    track_id: int | None
    box: BoxList
    area: Number
    """Pixels of the frame that moved."""
    speed_px_s: Number
    """Smoothed over the track."""
    distance_px: Number
    """The step since the object's previous sighting."""


class Alarm(WsMessage):
    """Something moved on an activated camera: a new event, or a new object in one.

    Alarms of one event are at least ``VIGIL_ALARM_GAP_S`` apart."""

    tag: ClassVar[str] = "alarm"
    type: Literal["alarm"] = "alarm"
    camera_id: int
    camera_name: str
    event_id: int
    """The event's id in ``GET /api/events``."""
    ts: Number
    """When, in UNIX seconds."""
    frame: int
    """The frame's number since Activate (0 is the first detected)."""
    boxes: list[BoxList]
    """Every object's box."""
    objects: list[AlarmObject]
    snapshot: str | None
    """URL of the annotated frame (JPEG); null when the disk refused it."""
    snapshot_id: int | None
    difference: str | None
    """URL of the difference picture (JPEG); null when the disk refused it."""
    node: str | None = None
    """The node that runs the camera (``VIGIL_NODE_NAME``): with several machines, any
    node's /ws carries every node's alarms (docs/scaling.md)."""


class MotionEnd(WsMessage):
    """An event has ended: ``VIGIL_QUIET_S`` passed without motion, or detection ended
    (Stop, a lost source, the camera deleted or its process restarted)."""

    tag: ClassVar[str] = "motion_end"
    type: Literal["motion_end"] = "motion_end"
    camera_id: int
    event_id: int
    ts: Number
    """The event's ``ended_at``: the time of its last moving frame (UNIX seconds)."""
    duration_s: Number
    """``ended_at - started_at``."""
    max_area: Number
    """The largest object's area, in pixels of the frame."""
    clip: str | None
    """URL of the event's clip (H.264 in MP4; it may still be recording its post-roll, and
    plays meanwhile); null when it has none (``VIGIL_CLIPS`` off, or the disk refused it)."""
    clip_s: Number | None
    """The clip's length in seconds, from ``VIGIL_PRE_ROLL_S`` before the event's first
    moving frame to ``VIGIL_POST_ROLL_S`` after its last; null without a clip."""
    node: str | None = None
    """The node that runs the camera (``VIGIL_NODE_NAME``): with several machines, any
    node's /ws carries every node's alarms (docs/scaling.md)."""


class Progress(WsMessage):
    """How far an uploaded video's analysis has got."""

    tag: ClassVar[str] = "progress"
    type: Literal["progress"] = "progress"
    analysis_id: str
    progress: Number = Field(ge=0, le=1)
    """0 at the start, 1 when done; at most 0.99 before."""
    frames: int | None = None
    """Frames analysed so far (not in the first and last message)."""


class SnapshotsDeleted(WsMessage):
    """Snapshots just deleted: by a user, or by retention. Only ids that existed."""

    tag: ClassVar[str] = "snapshots_deleted"
    type: Literal["snapshots_deleted"] = "snapshots_deleted"
    ids: list[int] = Field(min_length=1, max_length=DELETED_IDS_PER_MESSAGE)


class DetectSeconds(BaseModel):
    """A histogram of detection times: ``counts`` per bucket of
    ``app.workers.figures.DETECT_BUCKETS`` (seconds, upper bounds), the last above them
    all; ``sum`` in seconds."""

    model_config = ConfigDict(strict=True, extra="forbid", frozen=True)

    counts: list[int]
    sum: Number


CameraState = Literal["connecting", "live", "reconnecting", "error", "stopped"]


class CameraStatus(WsMessage):
    """A camera's state: on each change, every ``VIGIL_STATUS_INTERVAL_S`` while live, and
    after a ``PATCH`` (then with the settings it changed). One per camera when ``/ws``
    opens. The fields are those of ``GET /api/cameras`` that change as it runs."""

    tag: ClassVar[str] = "camera_status"
    type: Literal["status"] = "status"
    camera_id: int
    state: CameraState
    reason: str
    """Why it is not live, or ``preparing detection``; empty when all is well."""
    fps: Number
    """Frames a second, as measured."""
    source_fps: Number | None
    """The frame rate the source claims."""
    active: bool
    """Activated: detecting."""
    frames: int
    """Frames read since the worker started."""
    viewers: int
    """Live streams open on it."""
    processed: int
    """Frames detected."""
    objects: int
    """Objects in the last frame detected."""
    motion: Number
    """Share of the frame that moves (0..1)."""
    threshold: Number | None
    """The grey-level threshold in use; null while not detecting."""
    last_alarm: Number | None
    """UNIX time of the last alarm."""
    alarms: int
    """Alarms raised since the worker started."""
    detect_seconds: DetectSeconds
    """How long detection took per frame since the worker started (``/metrics``)."""
    process: int | None = None
    """The camera process it runs in (not after a ``PATCH``)."""
    storage_error: str | None = None
    """Only when snapshots or clips start or stop failing: why (null: saved again)."""
    name: str | None = None
    """This and the fields below: only after a ``PATCH`` that changed them."""
    source: str | None = None
    """Its password masked."""
    sensitivity: Number | None = None
    min_area: Number | None = None
    method: str | None = None
    show_mask: bool | None = None
    mask: list[list[list[Number]]] | None = None
    """Ignore zones: polygons of ``[x, y]`` fractions of the frame."""
    pinned_to: str | None = None
    """The only node that may run it (null: any); only after a ``PATCH`` that set it."""


AnalysisState = Literal["queued", "running", "done", "failed"]


class AnalysisStatus(WsMessage):
    """An uploaded video's analysis changed state."""

    tag: ClassVar[str] = "analysis_status"
    type: Literal["status"] = "status"
    analysis_id: str
    status: AnalysisState
    error: str | None = None
    """Only when it ends: why it failed (null when done)."""
    warnings: list[str] | None = None
    """Only when done with warnings: frames that did not decode, an early end."""


MESSAGES: tuple[type[WsMessage], ...] = (
    Alarm,
    MotionEnd,
    Progress,
    SnapshotsDeleted,
    CameraStatus,
    AnalysisStatus,
)


def _tag(value: Any) -> str | None:
    if isinstance(value, WsMessage):
        return value.tag
    if not isinstance(value, dict):
        return None
    kind = value.get("type")
    if kind == "status":
        return "camera_status" if "camera_id" in value else "analysis_status"
    return kind if isinstance(kind, str) else None


AnyMessage = Annotated[
    Annotated[Alarm, Tag(Alarm.tag)]
    | Annotated[MotionEnd, Tag(MotionEnd.tag)]
    | Annotated[Progress, Tag(Progress.tag)]
    | Annotated[SnapshotsDeleted, Tag(SnapshotsDeleted.tag)]
    | Annotated[CameraStatus, Tag(CameraStatus.tag)]
    | Annotated[AnalysisStatus, Tag(AnalysisStatus.tag)],
    Discriminator(_tag),
]
"""Any message: a ``status`` with ``camera_id`` is a camera's, else an analysis'."""

_ANY = TypeAdapter(AnyMessage)


def parse_message(wire: Wire) -> WsMessage:
    """The model of a message as ``/ws`` sent it (ValidationError if it is none)."""
    return _ANY.validate_python(wire)


class _Untitled(GenerateJsonSchema):
    """No ``title`` on each field: the name says it."""

    def field_title_should_be_set(self, schema: Any) -> bool:
        return False


def message_schemas() -> dict[str, dict[str, Any]]:
    """Each message's JSON Schema, by its model's name (as ``docs/websocket.md`` shows them)."""
    return {
        model.__name__: model.model_json_schema(schema_generator=_Untitled) for model in MESSAGES
    }
