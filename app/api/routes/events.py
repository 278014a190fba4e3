from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Query, Request

from app.api.routes.inputs import CameraFilter, TimeFilter
from app.api.services import services

router = APIRouter(prefix="/api", tags=["events"])


@router.get("/events")
def list_events(
    request: Request,
    camera_id: CameraFilter = None,
    since: TimeFilter = None,
    until: TimeFilter = None,
    limit: int = Query(200, ge=1, le=5000),
) -> list[dict[str, Any]]:
    """Motion events, newest first; ``since``/``until`` are Unix times in seconds and
    select the events going on at some time between them (an open one runs on)."""
    return services(request).database.events(camera_id, since, until, limit)
