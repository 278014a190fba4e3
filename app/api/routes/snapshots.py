"""The snapshot gallery: listing with filters, single pictures, bulk delete, streamed zip."""

from __future__ import annotations

import time
from collections.abc import Iterator
from functools import partial
from pathlib import Path
from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Query, Request
from fastapi.responses import FileResponse, Response, StreamingResponse
from pydantic import BaseModel, Field
from starlette.concurrency import run_in_threadpool

from app.api.routes.inputs import (
    MAX_ID,
    MAX_IDS,
    STRICT,
    CameraFilter,
    StrictJsonRoute,
    TimeFilter,
)
from app.api.services import Services, services
from app.storage.files import Fetched, stream_zip

router = APIRouter(prefix="/api", tags=["snapshots"], route_class=StrictJsonRoute)


def _view(row: dict[str, Any]) -> dict[str, Any]:
    out = {k: v for k, v in row.items() if k != "path"}
    out["url"] = f"/api/snapshots/{row['id']}.jpg"
    return out


def _ids(given: list[str] | None) -> list[int] | None:
    """``ids=1,2`` and ``ids=1&ids=2`` alike (and both at once). No ``ids``: no selection
    by number; an ``ids`` that names none (``ids=``) selects nothing, not everything."""
    if given is None:
        return None
    try:
        ids = [int(part) for part in ",".join(given).split(",") if part.strip()]
    except ValueError:
        raise HTTPException(422, "ids must be a comma-separated list of numbers") from None
    if len(ids) > MAX_IDS:
        raise HTTPException(422, f"ids must be at most {MAX_IDS:,} snapshot numbers")
    wrong = next((i for i in ids if not 0 <= i <= MAX_ID), None)
    if wrong is not None:
        raise HTTPException(422, f"ids are snapshot numbers from 0 to {MAX_ID:,}, not {wrong}")
    return ids


EndId = Annotated[int | None, Query(ge=0, le=MAX_ID)]
"""``since_id`` and ``until_id``: which of the snapshots taken at exactly ``since`` (from
this id on) or ``until`` (up to this id) are in; see ``Database.snapshots``."""


def _check_ends(
    since: float | None, since_id: int | None, until: float | None, until_id: int | None
) -> None:
    for name, end, given in (("since", since, since_id), ("until", until, until_id)):
        if given is not None and end is None:
            raise HTTPException(
                422, f"{name}_id needs {name}: it picks among the snapshots taken at exactly {name}"
            )


@router.get("/snapshots")
def list_snapshots(
    request: Request,
    camera_id: CameraFilter = None,
    since: TimeFilter = None,
    until: TimeFilter = None,
    kind: str | None = None,
    limit: int = Query(500, ge=1, le=10000),
    since_id: EndId = None,
    until_id: EndId = None,
) -> list[dict[str, Any]]:
    """Snapshots, newest first (by time, then id); ``kind`` is ``frame`` or ``difference``;
    times are Unix seconds. ``until`` with ``until_id`` (``since`` with ``since_id``) is a
    cursor: the next page after the last snapshot listed is ``until`` its ``ts`` and
    ``until_id`` its ``id`` less one, none skipped where snapshots share a time."""
    _check_ends(since, since_id, until, until_id)
    rows = services(request).database.snapshots(
        camera_id, since, until, kind, limit=limit, since_id=since_id, until_id=until_id
    )
    return [_view(r) for r in rows]


@router.get("/snapshots.zip")
def snapshots_zip(
    request: Request,
    camera_id: CameraFilter = None,
    since: TimeFilter = None,
    until: TimeFilter = None,
    kind: str | None = None,
    ids: Annotated[list[str] | None, Query()] = None,
    limit: int = Query(10000, ge=1, le=100000),
    since_id: EndId = None,
    until_id: EndId = None,
) -> StreamingResponse:
    """The selected snapshots as one zip, streamed as it is made; the filters are the
    listing's (a page range: ``since``/``since_id`` its oldest, ``until``/``until_id`` its
    newest)."""
    svc = services(request)
    _check_ends(since, since_id, until, until_id)
    rows = svc.database.snapshots(
        camera_id, since, until, kind, _ids(ids), limit, since_id=since_id, until_id=until_id
    )
    stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
    return StreamingResponse(
        _zip_entries(svc, rows),
        media_type="application/zip",
        headers={"Content-Disposition": f'attachment; filename="vigil-snapshots-{stamp}.zip"'},
    )


def _zip_entries(svc: Services, rows: list[dict[str, Any]]) -> Iterator[bytes]:
    def files() -> Iterator[tuple[Path | Fetched, str]]:
        for row in rows:
            try:
                path = svc.snapshots.path(row["path"])
            except ValueError:
                continue
            name = f"camera-{row['camera_id']}/{row['id']:06d}-{path.name}"
            holder = svc.holder(row, path)
            if holder is not None and svc.relay is not None:
                fetch = partial(svc.relay.fetch, holder, f"/api/snapshots/{row['id']}.jpg")
                yield Fetched(fetch, row["ts"]), name
            else:
                yield path, name

    return stream_zip(files())


@router.get("/snapshots/{snapshot_id}.jpg")
async def snapshot_file(request: Request, snapshot_id: int) -> Response:
    """The snapshot's JPEG; one another node made (and keeps) is asked of that node."""
    svc = services(request)
    row = await run_in_threadpool(svc.database.snapshot, snapshot_id)
    if row is None:
        raise HTTPException(404, f"no snapshot {snapshot_id}")
    path = svc.snapshots.path(row["path"])
    holder = svc.holder(row, path)
    if holder is not None and svc.relay is not None:
        return await svc.relay.get(request, holder, f"snapshot {snapshot_id}")
    if not path.is_file():
        raise HTTPException(404, f"snapshot {snapshot_id} file is missing")
    return FileResponse(path, media_type="image/jpeg")


class DeleteRequest(BaseModel):
    model_config = STRICT

    ids: list[Annotated[int, Field(ge=0, le=MAX_ID)]] = Field(min_length=1, max_length=MAX_IDS)


def _delete(svc: Services, ids: list[int]) -> dict[str, Any]:
    rows = svc.snapshots.delete_snapshots(svc.database, ids)
    return {"deleted": [r["id"] for r in rows]}


@router.post("/snapshots/delete")
def delete_snapshots(request: Request, body: DeleteRequest) -> dict[str, Any]:
    """Bulk delete (the gallery's selection)."""
    return _delete(services(request), body.ids)


@router.delete("/snapshots/{snapshot_id}")
def delete_snapshot(request: Request, snapshot_id: int) -> dict[str, Any]:
    result = _delete(services(request), [snapshot_id])
    if not result["deleted"]:
        raise HTTPException(404, f"no snapshot {snapshot_id}")
    return result
