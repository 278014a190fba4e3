"""``/ws``: alarm, motion_end, progress, snapshots_deleted and status messages, as JSON, as
they happen."""

from __future__ import annotations

import asyncio
import contextlib

from fastapi import APIRouter, WebSocket, WebSocketDisconnect

from app.api.services import services
from app.events.messages import CameraStatus

router = APIRouter()


@router.websocket("/ws")
async def websocket(socket: WebSocket) -> None:
    svc = services(socket)
    await socket.accept()
    queue = svc.bus.subscribe()
    receiver = asyncio.create_task(_ignore_incoming(socket))
    try:
        for worker in svc.cameras.all():  # Where every camera stands, first.
            await socket.send_json(CameraStatus(**worker.status()).wire())
        while True:
            getter = asyncio.create_task(queue.get())
            done, _ = await asyncio.wait({getter, receiver}, return_when=asyncio.FIRST_COMPLETED)
            if getter not in done:
                getter.cancel()
                return
            message = getter.result()
            if message is None:  # The server is stopping.
                with contextlib.suppress(Exception):
                    await socket.close(1001)
                return
            await socket.send_json(message)
    except (WebSocketDisconnect, RuntimeError):
        return
    finally:
        receiver.cancel()
        svc.bus.unsubscribe(queue)


async def _ignore_incoming(socket: WebSocket) -> None:
    with contextlib.suppress(WebSocketDisconnect, RuntimeError):
        while True:
            await socket.receive_text()
