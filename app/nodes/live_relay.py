"""Live frames of cameras another node runs, for a ``/ws/live`` client of this one.

Per client and node, one WebSocket to that node's ``/ws/live`` watching those of the
client's cameras it runs, at the client's width. Its messages are passed on as they come,
byte for byte (nothing decoded), into the client's slots: the newest frame of each camera
wins there, as for a camera that runs here, so a slow client still slows nobody. A node
that goes (or refuses) is asked again every ``RETRY_S`` while the client watches.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
from collections.abc import Callable

from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import WebSocketException

from app.nodes.relay import CONNECT_S, NotRelayableError, Relay
from app.workers.live_frames import message_camera

log = logging.getLogger("vigil.nodes")

RETRY_S = 1.0
MAX_MESSAGE = 64 << 20
"""Largest frame message taken from a node (a camera's own JPEG can be large)."""

Offer = Callable[[int, bytes], None]


def live_url(node_url: str) -> str:
    """``node_url``'s ``/ws/live`` (``http`` becomes ``ws``, ``https`` ``wss``)."""
    scheme, _, rest = node_url.partition("://")
    return f"{'wss' if scheme == 'https' else 'ws'}://{rest}/ws/live"


class NodeFeed:
    """One client's frames from ``node``: those of ``cameras``, each handed to ``offer``."""

    def __init__(self, relay: Relay, node: str, offer: Offer) -> None:
        self.relay = relay
        self.node = node
        self.offer = offer
        self.cameras: frozenset[int] = frozenset()
        self.width = 0
        self._changed = asyncio.Event()
        self._task = asyncio.create_task(self._run(), name=f"live from {node}")

    def watch(self, cameras: frozenset[int], width: int) -> None:
        if (cameras, width) != (self.cameras, self.width):
            self.cameras, self.width = cameras, width
            self._changed.set()

    def close(self) -> None:
        self._task.cancel()

    async def _run(self) -> None:
        failing = False
        while True:
            try:
                await self._follow()
            except (OSError, TimeoutError, NotRelayableError, WebSocketException) as failed:
                if not failing:  # Once per outage, not at every retry.
                    log.info("live frames from node %s: %s; retrying", self.node, failed)
                failing = True
            await asyncio.sleep(RETRY_S)

    async def _follow(self) -> None:
        """Take the node's frames until it goes: watch messages out, frames in."""
        peer = await asyncio.to_thread(self.relay.peer, self.node)
        async with connect(
            live_url(peer.url),
            additional_headers=self.relay.headers(peer),
            open_timeout=CONNECT_S,
            max_size=MAX_MESSAGE,
            compression=None,
        ) as socket:
            sending = asyncio.create_task(self._send_watches(socket))
            try:
                async for message in socket:
                    if isinstance(message, bytes):
                        camera = message_camera(message)
                        if camera in self.cameras:  # Not one unwatched since it came.
                            self.offer(camera, message)
            finally:
                sending.cancel()
                with contextlib.suppress(asyncio.CancelledError, WebSocketException):
                    await sending

    async def _send_watches(self, socket: ClientConnection) -> None:
        while True:
            self._changed.clear()
            watch = {"type": "watch", "cameras": sorted(self.cameras), "width": self.width}
            await socket.send(json.dumps(watch))
            await self._changed.wait()
