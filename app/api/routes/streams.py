"""Live pictures: MJPEG streams, and single frames for pages with many cameras.

A camera another node of the site runs is relayed from that node (``app.nodes.relay``)."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator

from fastapi import APIRouter, HTTPException, Request, Response
from fastapi.responses import StreamingResponse

from app.api.services import services
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


async def _here_or_relayed(request: Request, camera_id: int, stream: bool) -> Camera | Response:
    """The camera's worker when it runs here; else the answer of the node that runs it."""
    svc = services(request)
    worker = svc.cameras.get(camera_id)
    if worker is not None:
        return worker
    node = svc.node_of(camera_id)
    if node is None or svc.relay is None:
        raise HTTPException(404, f"no camera {camera_id}")
    return await svc.relay.get(request, node, f"camera {camera_id}", stream=stream)


async def _stream(request: Request, camera_id: int, kind: Kind) -> Response:
    found = await _here_or_relayed(request, camera_id, stream=True)
    if isinstance(found, Response):
        return found
    return StreamingResponse(_frames(request, found, kind), media_type=MJPEG_TYPE, headers=NO_CACHE)


@router.get("/{camera_id}/stream.mjpg")
async def stream(request: Request, camera_id: int) -> Response:
    """Annotated frames (boxes, track ids, trails; the motion mask when show_mask is on)."""
    return await _stream(request, camera_id, "picture")


@router.get("/{camera_id}/histogram.mjpg")
async def histogram_stream(request: Request, camera_id: int) -> Response:
    """The grey-level histogram of each frame, drawn as a picture."""
    return await _stream(request, camera_id, "histogram")


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


async def _frame(request: Request, camera_id: int, kind: Kind) -> Response:
    found = await _here_or_relayed(request, camera_id, stream=False)
    if isinstance(found, Response):
        return found
    data = await viewer_jpeg(await _latest(found, kind), kind)
    return Response(data, media_type="image/jpeg", headers=NO_CACHE)


@router.get("/{camera_id}/frame.jpg")
async def frame(request: Request, camera_id: int) -> Response:
    """The newest annotated frame, for pages that poll (more cameras than connections)."""
    return await _frame(request, camera_id, "picture")


@router.get("/{camera_id}/histogram.jpg")
async def histogram_frame(request: Request, camera_id: int) -> Response:
    return await _frame(request, camera_id, "histogram")
