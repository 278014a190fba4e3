"""Cameras: list, add, change, remove, Activate and Stop.

A camera's source is shown ``without_password`` (``rtsp://admin:***@host/...``) wherever
the API shows a camera; the worker gets the stored one. ``PATCH`` takes back the source
as shown (``with_stored_password``), so a client can send a camera back as it read it.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Request, Response
from pydantic import BaseModel, Field, field_validator

from app.api.routes.inputs import STRICT, StrictJsonRoute, check_min_area, is_control
from app.api.services import services
from app.nodes.relay import is_relayed
from app.sources.live import MASK, has_masked_password, parse_source, with_stored_password
from app.vision.motion import DEFAULT_METHOD, METHODS
from app.vision.zones import as_polygons

router = APIRouter(prefix="/api/cameras", tags=["cameras"], route_class=StrictJsonRoute)

MAX_ZONE_POINTS = 1000
"""Points in one ignore zone: plenty for a hand-drawn outline, bounded for fillPoly."""
Sensitivity = Annotated[float, Field(ge=1, le=255, allow_inf_nan=False)]
"""Grey-level threshold 1..255, lower = more sensitive; null = automatic."""
MinArea = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Zones = list[Annotated[list[list[float]], Field(max_length=MAX_ZONE_POINTS)]]


def _check_text(value: str | None) -> str | None:
    if value is not None and any(is_control(c) for c in value):
        raise ValueError("must not contain control characters")
    return value


def _check_method(value: str | None) -> str | None:
    if value is not None and value not in METHODS:
        raise ValueError(f"unknown method {value!r}; choose from {', '.join(METHODS)}")
    return value


def _check_source(value: str | None) -> str | None:
    if value is not None:
        _check_text(value)
        parse_source(value)
        return value.strip()
    return value


def _check_new_source(value: str) -> str:
    """A new camera's source. A password that reads as the mask was copied from what the
    API shows, not typed: refused."""
    if has_masked_password(value):
        raise ValueError(
            f"{MASK} is how Vigil shows a stored password, not a password: type the password"
            f" (one that really is {MASK} is written %2A%2A%2A)"
        )
    return value


class CameraIn(BaseModel):
    model_config = STRICT

    name: str = Field(min_length=1, max_length=100)
    source: str = Field(min_length=1, max_length=2000)
    sensitivity: Sensitivity | None = None
    min_area: MinArea | None = None
    method: str | None = None

    _name = field_validator("name")(_check_text)
    _method = field_validator("method")(_check_method)
    _min_area = field_validator("min_area")(check_min_area)
    _source = field_validator("source")(_check_source)
    _new_source = field_validator("source")(_check_new_source)


class CameraPatch(BaseModel):
    model_config = STRICT

    name: str | None = Field(default=None, min_length=1, max_length=100)
    source: str | None = Field(default=None, min_length=1, max_length=2000)
    sensitivity: Sensitivity | None = None
    min_area: MinArea | None = None
    method: str | None = None
    show_mask: bool | None = None
    mask: Zones | None = Field(default=None, max_length=64)
    """Ignore zones: polygons of [x, y] fractions of the frame; null or [] clears them."""
    pinned_to: str | None = Field(default=None, min_length=1, max_length=100)
    """The only node that may run the camera (a USB camera's); null: any node."""

    _name = field_validator("name")(_check_text)
    _pinned_to = field_validator("pinned_to")(_check_text)
    _method = field_validator("method")(_check_method)
    _min_area = field_validator("min_area")(check_min_area)

    @field_validator("mask")
    @classmethod
    def _check_mask(cls, value: Zones | None) -> Zones:
        polygons = as_polygons(value or [])
        return [[list(point) for point in polygon] for polygon in polygons]

    _source = field_validator("source")(_check_source)


def _camera_or_404(request: Request, camera_id: int) -> dict[str, Any]:
    camera = services(request).database.camera(camera_id)
    if camera is None:
        raise HTTPException(404, f"no camera {camera_id}")
    return camera


@router.get("")
def list_cameras(request: Request) -> list[dict[str, Any]]:
    svc = services(request)
    ask_others = not is_relayed(request)  # A node asking is told of this one's cameras.
    return [svc.camera_view(c, ask_others) for c in svc.database.cameras()]


@router.post("")
def add_camera(request: Request, body: CameraIn) -> dict[str, Any]:
    svc = services(request)
    camera_id = svc.database.add_camera(
        body.name,
        body.source,
        body.method or DEFAULT_METHOD,
        svc.settings.default_min_area if body.min_area is None else body.min_area,
        body.sensitivity,
    )
    camera = svc.database.camera(camera_id)
    if camera is None:  # Deleted by another request in the meantime.
        raise HTTPException(404, f"no camera {camera_id}")
    svc.add_camera(camera)
    return {"id": camera_id}


@router.get("/{camera_id}")
def get_camera(request: Request, camera_id: int) -> dict[str, Any]:
    return services(request).camera_view(_camera_or_404(request, camera_id))


@router.patch("/{camera_id}")
def change_camera(request: Request, camera_id: int, body: CameraPatch) -> dict[str, Any]:
    svc = services(request)
    before = _camera_or_404(request, camera_id)
    changes = {k: getattr(body, k) for k in body.model_fields_set}
    for key in ("name", "source", "min_area", "method", "show_mask"):
        if key in changes and changes[key] is None:
            raise HTTPException(422, f"{key} cannot be null")
    if "source" in changes:
        try:  # The source as GET shows it, password masked, keeps the password.
            changes["source"] = with_stored_password(changes["source"], before["source"])
        except ValueError as exc:
            raise HTTPException(422, str(exc)) from None
    view = svc.change_camera(camera_id, before, changes)
    if view is None:  # Deleted by another request in the meantime.
        raise HTTPException(404, f"no camera {camera_id}")
    return view


@router.delete("/{camera_id}", status_code=204)
def delete_camera(request: Request, camera_id: int) -> Response:
    svc = services(request)
    _camera_or_404(request, camera_id)
    svc.delete_camera(camera_id)
    return Response(status_code=204)


class NoSettings(BaseModel):
    """Activate and Stop take no settings: an empty object at most (or no body at all),
    so that a field sent to them is refused as the other routes refuse it, not ignored."""

    model_config = STRICT


def _set_active(request: Request, camera_id: int, active: bool) -> dict[str, Any]:
    svc = services(request)
    _camera_or_404(request, camera_id)
    view = svc.set_active(camera_id, active)
    if view is None:  # Deleted by another request in the meantime.
        raise HTTPException(404, f"no camera {camera_id}")
    return view


@router.post("/{camera_id}/activate")
def activate(request: Request, camera_id: int, body: NoSettings | None = None) -> dict[str, Any]:
    """Start detecting (the paper's Activate trigger): alarms from the next frame."""
    return _set_active(request, camera_id, True)


@router.post("/{camera_id}/stop")
def stop(request: Request, camera_id: int, body: NoSettings | None = None) -> dict[str, Any]:
    """Stop detecting; the live picture goes on. An open event ends (``motion_end``)."""
    return _set_active(request, camera_id, False)
