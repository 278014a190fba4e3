"""Motion events with their clips, deleting them, and a camera's activity over time."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Query, Request, Response
from pydantic import BaseModel, Field
from starlette.concurrency import run_in_threadpool

from app.api.ranges import ranged_file
from app.api.routes.inputs import MAX_ID, MAX_IDS, STRICT, CameraFilter, StrictJsonRoute, TimeFilter
from app.api.services import Services, services
from app.recording.recorder import clip_url
from app.storage.clips import complete_length

router = APIRouter(prefix="/api", tags=["events"], route_class=StrictJsonRoute)

MAX_STEPS = 10_000
"""Steps one activity request may ask for: a day by 10 s, an hour by the second."""
DAY_S = 86_400


def _views(svc: Services, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Events as the API shows them: the clip's URL, not its path; the first snapshot."""
    firsts = svc.database.first_snapshots([row["id"] for row in rows])
    out = []
    for row in rows:
        view = {k: v for k, v in row.items() if k != "clip_path"}
        view["clip"] = clip_url(row["id"]) if row["clip_path"] else None
        snapshot_id = firsts.get(row["id"])
        view["snapshot"] = None if snapshot_id is None else f"/api/snapshots/{snapshot_id}.jpg"
        out.append(view)
    return out


@router.get("/events")
def list_events(
    request: Request,
    camera_id: CameraFilter = None,
    since: TimeFilter = None,
    until: TimeFilter = None,
    limit: int = Query(200, ge=1, le=5000),
) -> list[dict[str, Any]]:
    """Motion events, newest first; ``since``/``until`` are Unix times in seconds and
    select the events going on at some time between them (an open one runs on). Each
    has its ``clip`` (URL, or null) and ``clip_s`` (null while it is being recorded)."""
    svc = services(request)
    return _views(svc, svc.database.events(camera_id, since, until, limit))


def _event_or_404(svc: Services, event_id: int) -> dict[str, Any]:
    row = svc.database.event(event_id)
    if row is None:
        raise HTTPException(404, f"no event {event_id}")
    return row


@router.get("/events/{event_id}")
def get_event(request: Request, event_id: int) -> dict[str, Any]:
    svc = services(request)
    return _views(svc, [_event_or_404(svc, event_id)])[0]


@router.get("/events/{event_id}/clip.mp4")
async def event_clip(request: Request, event_id: int) -> Response:
    """The event's clip, H.264 in MP4, whole or the range asked for (``Range``: 206). One
    still being recorded is served as far as its last whole fragment. One another node
    recorded (and keeps) is asked of that node."""
    svc = services(request)
    row = await run_in_threadpool(_event_or_404, svc, event_id)
    if not row["clip_path"]:
        why = row["clip_error"] or "none was recorded"
        raise HTTPException(404, f"event {event_id} has no clip: {why}")
    try:
        path = svc.clips.path(row["clip_path"])
    except ValueError:
        raise HTTPException(404, f"event {event_id} has no clip") from None
    holder = svc.holder(row, path)
    if holder is not None and svc.relay is not None:
        return await svc.relay.get(request, holder, f"event {event_id}'s clip")
    return await run_in_threadpool(_clip_file, request, event_id, row, path)


def _clip_file(request: Request, event_id: int, row: dict[str, Any], path: Path) -> Response:
    recording = row["clip_s"] is None
    length = complete_length(path) if recording else None
    if recording and not length:
        raise HTTPException(404, f"event {event_id}'s clip has no frames yet: try again")
    return ranged_file(
        request,
        path,
        "video/mp4",
        length,
        filename=f"event-{event_id}.mp4",
        cache="no-cache" if recording else "private, max-age=3600",
    )


class DeleteRequest(BaseModel):
    model_config = STRICT

    ids: list[Annotated[int, Field(ge=0, le=MAX_ID)]] = Field(min_length=1, max_length=MAX_IDS)


def _delete(svc: Services, ids: list[int]) -> dict[str, Any]:
    """Delete the events that have ended, with their snapshots (every page told) and clips;
    those still going on (or still recording their clip) stay, listed as ``ongoing``."""
    db = svc.database
    found = [row for i in dict.fromkeys(ids) if (row := db.event(i)) is not None]
    ongoing = [
        row["id"]
        for row in found
        if row["ended_at"] is None or (row["clip_path"] and row["clip_s"] is None)
    ]
    chosen = [row["id"] for row in found if row["id"] not in ongoing]
    snapshot_ids = db.snapshot_ids_of(chosen)
    if snapshot_ids:
        svc.snapshots.delete_snapshots(db, snapshot_ids)
    deleted = db.delete_events(chosen)
    for row in deleted:
        if row["clip_path"]:
            svc.clips.delete(row["clip_path"])
    return {"deleted": [row["id"] for row in deleted], "ongoing": ongoing}


@router.post("/events/delete")
def delete_events(request: Request, body: DeleteRequest) -> dict[str, Any]:
    """Bulk delete: ``{"deleted": [ids], "ongoing": [ids]}`` (ongoing: not deleted, the
    event or its clip is still being recorded)."""
    return _delete(services(request), body.ids)


@router.delete("/events/{event_id}")
def delete_event(request: Request, event_id: int) -> dict[str, Any]:
    """The event with its snapshots and clip. 409 while it goes on (or its clip records)."""
    result = _delete(services(request), [event_id])
    if result["ongoing"]:
        raise HTTPException(409, f"event {event_id} is still going on: delete it once it ends")
    if not result["deleted"]:
        raise HTTPException(404, f"no event {event_id}")
    return result


def _finite(name: str, value: float | None) -> float | None:
    if value is not None and not math.isfinite(value):
        raise HTTPException(422, f"{name} must be a finite number of UNIX seconds")
    return value


@router.get("/cameras/{camera_id}/activity")
def camera_activity(
    request: Request,
    camera_id: int,
    since: float | None = None,
    until: float | None = None,
    step: float = 60.0,
) -> dict[str, Any]:
    """How busy the camera was: per ``step`` seconds from ``since`` to ``until`` (UNIX
    seconds; default the last day by the minute), the largest share of the picture that
    moved (``motion``, 0..1; null where the camera was not activated) and how many events
    started (``events``)."""
    svc = services(request)
    if not 0 <= camera_id <= MAX_ID or svc.database.camera(camera_id) is None:
        raise HTTPException(404, f"no camera {camera_id}")
    _finite("since", since)
    _finite("until", until)
    if not math.isfinite(step) or step < 1:
        raise HTTPException(422, f"step must be at least 1 second, not {step:g}")
    end = until if until is not None else time.time()
    start = since if since is not None else end - DAY_S
    if start >= end:
        raise HTTPException(422, f"since ({start:g}) must be before until ({end:g})")
    count = math.ceil((end - start) / step)
    if count > MAX_STEPS:
        raise HTTPException(
            422,
            f"{count:,} steps of {step:g} s from since to until: at most {MAX_STEPS:,};"
            " ask for a larger step or a shorter span",
        )
    found = svc.database.activity(camera_id, start, end, step)
    steps = []
    for index in range(count):
        motion, events = found.get(index, (None, 0))
        steps.append({"ts": start + index * step, "motion": motion, "events": events})
    return {"camera_id": camera_id, "since": start, "until": end, "step": step, "steps": steps}
