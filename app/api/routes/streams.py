"""Live pictures: MJPEG streams, and single frames for pages with many cameras."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator

from fastapi import APIRouter, HTTPException, Request, Response
from fastapi.responses import StreamingResponse

from app.api.services import services, worker_or_404
from app.vision.annotate import status_card
from app.workers.camera_host import Camera
from app.workers.hub import Kind, Picture, encode_jpeg, viewer_jpeg

router = APIRouter(prefix="/api/cameras", tags=["streams"])

BOUNDARY = "frame"
MJPEG_TYPE = f"multipart/x-mixed-replace; boundary={BOUNDARY}"
NO_CACHE = {"Cache-Control": "no-store, no-cache, must-revalidate", "Pragma": "no-cache"}
SENDING = ("connecting", "live")
"""Camera states in which pictures come (or are about to): in any other it is down."""


def mjpeg_part(data: bytes) -> bytes:
    head = (
        f"--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {len(data)}\r\n\r\n"
    ).encode()
    return head + data + b"\r\n"


async def _frames(request: Request, camera: Camera, kind: Kind) -> AsyncIterator[bytes]:
    """The camera's frames as MJPEG parts. While it is down (``error``, ``reconnecting``)
    a viewer gets one card saying so and why, then its frames as soon as it is back."""
    svc = services(request)
    hub = camera.hub
    seq = 0
    carded: tuple[str, str] | None = None  # The state the last card told of.
    with hub.watch(kind):
        while not svc.closing and not hub.closed:
            item = await hub.next(seq, 1.0, kind)
            if item is None:
                # Starlette's response lets a client that went go at once where the
                # server reports it (uvicorn does); where it does not, a write to the
                # closed connection fails. With no frame to write, this asks, each
                # second; not each frame, where asking cost this loop a third of its work.
                if await request.is_disconnected():
                    return
                state = (camera.state, camera.reason)
                if state[0] not in SENDING and state != carded:
                    carded = state
                    card = status_card(f"camera {state[0]}", state[1])
                    yield mjpeg_part(await asyncio.to_thread(encode_jpeg, card))
                continue
            carded = None
            seq = item.seq
            yield mjpeg_part(await viewer_jpeg(item, kind))


@router.get("/{camera_id}/stream.mjpg")
async def stream(request: Request, camera_id: int) -> StreamingResponse:
    """Annotated frames (boxes, track ids, trails; the motion mask when show_mask is on)."""
    worker = worker_or_404(request, camera_id)
    return StreamingResponse(
        _frames(request, worker, "picture"), media_type=MJPEG_TYPE, headers=NO_CACHE
    )


@router.get("/{camera_id}/histogram.mjpg")
async def histogram_stream(request: Request, camera_id: int) -> StreamingResponse:
    """The grey-level histogram of each frame, drawn as a picture."""
    worker = worker_or_404(request, camera_id)
    return StreamingResponse(
        _frames(request, worker, "histogram"), media_type=MJPEG_TYPE, headers=NO_CACHE
    )


async def _latest(camera: Camera, kind: Kind) -> Picture:
    """A fresh frame: a poller counts as a viewer until it has one (a camera process
    sends pictures only while someone watches)."""
    item = None
    if camera.state in SENDING:
        with camera.hub.watch(kind):
            latest = camera.hub.latest
            item = await camera.hub.next(latest.seq if latest else 0, 3.0, kind)
    if item is None:
        raise HTTPException(
            503,
            f"no picture now: camera is {camera.state}"
            + (f" ({camera.reason})" if camera.reason else ""),
        )
    return item


@router.get("/{camera_id}/frame.jpg")
async def frame(request: Request, camera_id: int) -> Response:
    """The newest annotated frame, for pages that poll (more cameras than connections)."""
    item = await _latest(worker_or_404(request, camera_id), "picture")
    data = await viewer_jpeg(item, "picture")
    return Response(data, media_type="image/jpeg", headers=NO_CACHE)


@router.get("/{camera_id}/histogram.jpg")
async def histogram_frame(request: Request, camera_id: int) -> Response:
    item = await _latest(worker_or_404(request, camera_id), "histogram")
    data = await viewer_jpeg(item, "histogram")
    return Response(data, media_type="image/jpeg", headers=NO_CACHE)
