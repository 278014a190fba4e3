"""Uploaded videos: analysed in a separate process, followed live, downloaded when done."""

from __future__ import annotations

import asyncio
import json
import math
import re
import shutil
import uuid
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any, BinaryIO

from fastapi import APIRouter, Form, HTTPException, Request, Response, UploadFile
from fastapi.responses import FileResponse, JSONResponse, StreamingResponse
from starlette.concurrency import run_in_threadpool

from app.api.ranges import ranged_file
from app.api.routes.inputs import check_min_area, is_control
from app.api.routes.streams import MJPEG_TYPE, NO_CACHE, mjpeg_part
from app.api.services import Services, services
from app.events.messages import AnalysisStatus
from app.vision.motion import METHODS
from app.vision.pipeline import check_detect_width
from app.workers.analysis_child import LIVE_FRAME

router = APIRouter(prefix="/api/analyses", tags=["analyses"])

FINISHED = ("done", "failed")
UPLOAD_FIELDS = frozenset({"file", "method", "sensitivity", "min_area", "detect_width"})
"""The parts of an upload; any other is refused."""


class UploadTooLargeError(Exception):
    pass


def display_name(filename: str | None) -> str:
    """The upload's own name, for people: no folders (either slash), no control characters.

    It is never part of a path here: the file is kept as ``input<suffix>``.
    """
    name = re.split(r"[/\\]", filename or "")[-1]
    name = "".join(c for c in name if not is_control(c)).strip()[:200]
    return name if name not in ("", ".", "..") else "upload"


def _copy_limited(source: BinaryIO, target: Path, limit: int) -> int:
    written = 0
    with target.open("wb") as out:
        while block := source.read(1 << 20):
            written += len(block)
            if written > limit:
                raise UploadTooLargeError
            out.write(block)
    return written


@router.post("", status_code=202)
async def upload(
    request: Request,
    file: UploadFile,
    method: str | None = Form(None),
    sensitivity: float | None = Form(None),
    min_area: float | None = Form(None),
    detect_width: int | None = Form(None),
) -> dict[str, Any]:
    """Upload a video (multipart field ``file``); it is analysed in the background."""
    svc = services(request)
    limit = svc.settings.max_upload_mb * 1024 * 1024
    if method is not None and method != "" and method not in METHODS:
        raise HTTPException(422, f"unknown method {method!r}; choose from {', '.join(METHODS)}")
    if sensitivity is not None and not 1 <= sensitivity <= 255:
        raise HTTPException(422, "sensitivity must be between 1 and 255 grey levels")
    if min_area is not None and not (math.isfinite(min_area) and min_area >= 0):
        raise HTTPException(422, "min_area must be a number of pixels, 0 or more")
    try:
        check_min_area(min_area)
    except ValueError as exc:
        raise HTTPException(422, str(exc)) from None
    if detect_width is not None:
        try:
            check_detect_width(detect_width)
        except ValueError as exc:
            raise HTTPException(422, f"detect_width {exc}") from None
    unknown = sorted(set((await request.form()).keys()) - UPLOAD_FIELDS)
    if unknown:  # A misspelt setting (min-area) is an error, as in the camera routes.
        raise HTTPException(
            422,
            f"unknown field{'s' if len(unknown) > 1 else ''} {', '.join(map(repr, unknown))};"
            f" an upload has {', '.join(sorted(UPLOAD_FIELDS))}",
        )
    analysis_id = uuid.uuid4().hex[:12]
    folder = svc.analyses.folder(analysis_id)
    folder.mkdir(parents=True, exist_ok=True)
    filename = display_name(file.filename)
    suffix = Path(filename).suffix.lower()
    if not re.fullmatch(r"\.[a-z0-9]{1,5}", suffix):
        suffix = ".bin"
    try:
        size = await asyncio.to_thread(_copy_limited, file.file, folder / f"input{suffix}", limit)
    except UploadTooLargeError:
        shutil.rmtree(folder, ignore_errors=True)
        raise HTTPException(413, f"upload larger than {svc.settings.max_upload_mb} MB") from None
    if size == 0:
        shutil.rmtree(folder, ignore_errors=True)
        raise HTTPException(422, "the uploaded file is empty")
    options = {
        "method": method or None,
        "sensitivity": sensitivity,
        "min_area": min_area,
        "detect_width": detect_width,
    }
    svc.database.add_analysis(analysis_id, filename, options)
    svc.analyses.submit(analysis_id)
    svc.bus.publish(AnalysisStatus(analysis_id=analysis_id, status="queued"))
    return {"id": analysis_id, "url": f"/api/analyses/{analysis_id}"}


def _view(svc: Services, row: dict[str, Any], full: bool) -> dict[str, Any]:
    analysis_id = row["id"]
    base = f"/api/analyses/{analysis_id}"
    progress = row["progress"]
    if row["status"] == "running":
        progress = svc.analyses.progress.get(analysis_id, progress)
    out: dict[str, Any] = {
        "id": analysis_id,
        "filename": row["filename"],
        "status": row["status"],
        "progress": round(float(progress), 4),
        "error": row["error"],
        "options": row["options"],
        "created_at": row["created_at"],
        "finished_at": row["finished_at"],
        "node": row["node"],
        "links": {
            "self": base,
            "stream": f"{base}/stream.mjpg",
            "tracks": f"{base}/tracks.csv",
            "annotated": f"{base}/annotated.avi",
            "annotated_mp4": f"{base}/annotated.mp4",
            "report": f"{base}/report.json",
            "report_html": f"{base}/report.html",
        },
        "report": None,
        "events": None,
    }
    if full and row["status"] == "done":
        out_dir = svc.analyses.folder(analysis_id) / "out"
        report_path = out_dir / "report.json"
        if report_path.is_file():
            out["report"] = json.loads(report_path.read_text())
        events_path = out_dir / "events.json"  # The chapters of annotated.mp4.
        if events_path.is_file():
            out["events"] = json.loads(events_path.read_text()).get("events")
    return out


def _row_or_404(svc: Services, analysis_id: str) -> dict[str, Any]:
    if not re.fullmatch(r"[0-9a-f]{1,32}", analysis_id):
        raise HTTPException(404, f"no analysis {analysis_id}")
    row = svc.database.analysis(analysis_id)
    if row is None:
        raise HTTPException(404, f"no analysis {analysis_id}")
    return row


@router.get("")
def list_analyses(request: Request) -> list[dict[str, Any]]:
    svc = services(request)
    return [_view(svc, row, False) for row in svc.database.analyses()]


@router.get("/{analysis_id}")
async def get_analysis(request: Request, analysis_id: str) -> Response:
    """Status (queued, running, done, failed), progress 0..1, the report when done, the error.
    Done on another node (whose disk holds the report): as that node shows it."""
    svc = services(request)
    row = await run_in_threadpool(_row_or_404, svc, analysis_id)
    report = svc.analyses.folder(analysis_id) / "out" / "report.json"
    holder = svc.holder(row, report) if row["status"] == "done" else None
    if holder is not None and svc.relay is not None:
        return await svc.relay.get(request, holder, f"analysis {analysis_id}")
    return JSONResponse(await run_in_threadpool(_view, svc, row, True))


async def _output(
    request: Request, analysis_id: str, name: str, answer: Callable[[Path], Response]
) -> Response:
    """``answer`` for the analysis's output file ``name``, once it is done; of an analysis
    another node ran (its disk holds the files), that node's answer."""
    svc = services(request)
    row = await run_in_threadpool(_row_or_404, svc, analysis_id)
    path = svc.analyses.folder(analysis_id) / "out" / name
    holder = svc.holder(row, path)
    if holder is not None and svc.relay is not None:
        return await svc.relay.get(request, holder, f"analysis {analysis_id}'s {name}")
    if row["status"] != "done" or not path.is_file():
        raise HTTPException(404, f"{name} is not ready: the analysis is {row['status']}")
    return await run_in_threadpool(answer, path)


def _file(media_type: str, filename: str | None = None) -> Callable[[Path], Response]:
    return lambda path: FileResponse(path, media_type=media_type, filename=filename)


@router.get("/{analysis_id}/tracks.csv")
async def tracks(request: Request, analysis_id: str) -> Response:
    csv = _file("text/csv", f"tracks-{analysis_id}.csv")
    return await _output(request, analysis_id, "tracks.csv", csv)


@router.get("/{analysis_id}/annotated.avi")
async def annotated(request: Request, analysis_id: str) -> Response:
    avi = _file("video/x-msvideo", f"annotated-{analysis_id}.avi")
    return await _output(request, analysis_id, "annotated.avi", avi)


@router.get("/{analysis_id}/annotated.mp4")
async def annotated_mp4(request: Request, analysis_id: str) -> Response:
    """The annotated video in H.264, for the page's player: whole, or the range asked for."""
    return await _output(
        request,
        analysis_id,
        "annotated.mp4",
        lambda path: ranged_file(
            request, path, "video/mp4", filename=f"annotated-{analysis_id}.mp4", cache="private"
        ),
    )


@router.get("/{analysis_id}/report.json")
async def report(request: Request, analysis_id: str) -> Response:
    return await _output(
        request,
        analysis_id,
        "report.json",
        lambda path: JSONResponse(json.loads(path.read_text())),
    )


@router.get("/{analysis_id}/report.html")
async def report_html(request: Request, analysis_id: str) -> Response:
    return await _output(request, analysis_id, "report.html", _file("text/html"))


@router.get("/{analysis_id}/stream.mjpg")
async def stream(request: Request, analysis_id: str) -> Response:
    """Annotated frames while the analysis runs; ends with its last frame."""
    svc = services(request)
    row = await run_in_threadpool(_row_or_404, svc, analysis_id)
    live = svc.analyses.folder(analysis_id) / "out" / LIVE_FRAME
    holder = svc.holder(row, live)
    if holder is not None and svc.relay is not None:
        what = f"analysis {analysis_id}'s frames"
        return await svc.relay.get(request, holder, what, stream=True)
    if row["status"] in FINISHED and not live.is_file():
        raise HTTPException(404, f"no frames to show: the analysis is {row['status']}")
    return StreamingResponse(
        _follow(request, svc, analysis_id, live), media_type=MJPEG_TYPE, headers=NO_CACHE
    )


async def _follow(
    request: Request, svc: Services, analysis_id: str, live: Path
) -> AsyncIterator[bytes]:
    last_mtime = 0
    while not svc.closing:
        row = svc.database.analysis(analysis_id)
        finished = row is None or row["status"] in FINISHED
        try:
            mtime = live.stat().st_mtime_ns
            if mtime != last_mtime:
                data = live.read_bytes()
                last_mtime = mtime
                yield mjpeg_part(data)
        except OSError:
            pass
        if finished or await request.is_disconnected():
            return
        await asyncio.sleep(0.1)
