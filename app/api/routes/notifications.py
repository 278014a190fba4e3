"""Notification targets: list, add, delete and test (docs/notifications.md).

A target is an Apprise URL, for every camera or some. Its secrets are masked wherever the
API shows it (``app.notify.targets.masked``), and no refusal echoes it: a URL Apprise
cannot use is a 422 saying why, with nothing stored.
"""

from __future__ import annotations

import asyncio
from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Request, Response
from pydantic import BaseModel, Field

from app.api.routes.inputs import MAX_ID, STRICT, StrictJsonRoute
from app.api.services import services
from app.notify.notifier import DuplicateTargetError, FixedTargetError
from app.notify.targets import TargetError
from app.sources.live import MASK

router = APIRouter(prefix="/api/notifications", tags=["notifications"], route_class=StrictJsonRoute)

MAX_CAMERAS = 1000
CameraId = Annotated[int, Field(ge=0, le=MAX_ID)]


class TargetIn(BaseModel):
    model_config = STRICT

    url: str
    """An Apprise URL (``ntfys://topic``, ``tgram://token/chat``, ``mailtos://...``). Not
    checked here but by Apprise, so that no refusal echoes it."""
    cameras: list[CameraId] | None = Field(default=None, max_length=MAX_CAMERAS)
    """The cameras whose events it is told of; null: every camera."""


@router.get("")
def list_targets(request: Request) -> list[dict[str, Any]]:
    """Every target, its URL masked, with its counts (``sent``, ``failed``, ``pending``)
    and state (``failing``, ``last_error`` and ``last_error_at``) since the server started."""
    return services(request).notifier.views()


@router.post("", status_code=201)
def add_target(request: Request, body: TargetIn) -> dict[str, Any]:
    svc = services(request)
    if MASK in body.url:
        raise HTTPException(
            422,
            f"{MASK} is how Vigil shows a secret, not a secret: type the URL in full"
            f" (a secret that really is {MASK} is written %2A%2A%2A)",
        )
    cameras = None
    if body.cameras is not None:
        cameras = sorted(set(body.cameras))
        if not cameras:
            raise HTTPException(422, "cameras: give at least one camera id, or null for all")
        missing = [c for c in cameras if svc.database.camera(c) is None]
        if missing:
            raise HTTPException(422, f"cameras: no camera {', '.join(map(str, missing))}")
    try:
        return svc.notifier.add(body.url, cameras)
    except TargetError as exc:
        raise HTTPException(422, str(exc)) from None
    except DuplicateTargetError as exc:
        raise HTTPException(409, str(exc)) from None


@router.delete("/{target_id}", status_code=204)
def delete_target(request: Request, target_id: int) -> Response:
    try:
        deleted = services(request).notifier.remove(target_id)
    except FixedTargetError as exc:
        raise HTTPException(409, str(exc)) from None
    if not deleted:
        raise HTTPException(404, f"no notification target {target_id}")
    return Response(status_code=204)


@router.post("/{target_id}/test")
async def test_target(request: Request, target_id: int) -> dict[str, Any]:
    """Send a test message now (once, within ``VIGIL_NOTIFY_TIMEOUT_S``): ``ok``, and if
    not, ``error``, why; ``elapsed_s``."""
    outcome = await asyncio.to_thread(services(request).notifier.test, target_id)
    if outcome is None:
        raise HTTPException(404, f"no notification target {target_id}")
    return {"ok": outcome.ok, "error": outcome.error, "elapsed_s": outcome.elapsed_s}
